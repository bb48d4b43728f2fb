"""A design study's inputs (mm, N): the axes of the grid (``START:STOP:COUNT`` or lists),
study files (TOML, one ``[sweep]`` table), and the plan: one task per geometry and
material, each at every load, keyed by a hash of all its resolved inputs and of the code
that analyses it, so that a re-run recognises a finished task and re-runs one whose inputs
or code changed. Invalid variants
(rules of docs/design.md §2) are planned with the rule they break, never analysed.
"""
from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path

from pipeline.inputs.case import Case, resolve
from pipeline.inputs.options import Outputs, RunOptions, check_options
from pipeline.inputs.tomlfile import read_toml
from pipeline.cache.codekey import code_key
from pipeline.errors import InputError
from pipeline.study.screening import SCREEN_MAX_MESH_FACTOR

# A study file's [sweep] keys and their TOML types.
TOML_NAMES = {str: "a string", int: "an integer", float: "a number", dict: "a table", list: "an array of numbers",
              bool: "true or false"}
STUDY_KEYS = {"size": (str,), "case": (str,), "dims": (dict,), "load": (str, int, float, list), "levels": (int,),
              "ratio": (int, float), "mesh_factor": (int, float), "out": (str,), "screen": (bool,)}


@dataclass(frozen=True)
class Study:
    """A design study as asked (mm, N): the case it starts from (a hook number ``size`` or a
    case file, or every hook number of ``sizes``), what every variant shares (``base``: the
    case file's keys), the axes of its grid (``dims.<name>`` or case fields, values), the
    hook loads (empty: each case's own), each variant's meshes (``levels`` at ``ratio``),
    whether each also varies its assumed inputs (``sensitivity``), whether the study is
    screened (``screen``), the memory a variant may use (GiB; None: the memory free) and the
    inputs the user gave (``given``: the case file's keys, and "ratio" when given on the
    command line; pipeline.inputs.options.check_given refuses those a variant cannot use)."""

    size: str | None
    case_file: Path | None
    base: dict
    axes: dict[str, list[float]]
    loads: list[float]
    levels: int = 3
    ratio: float = 1.3
    sizes: list[str] | None = None
    sensitivity: bool = False
    screen: bool = False
    memory_limit_gb: float | None = None
    given: frozenset[str] = frozenset()


def variant_options(study: Study, loads: tuple[float, ...] = ()) -> RunOptions:
    """How each variant of ``study`` is run at ``loads`` (N; one load: its own alone): its
    levels meshes at the study's ratio, no tolerance loop, the sensitivity section when the
    study asks for it, no formula-load sections (the study's table does not read them), no
    fields and no mesh file (its question is its peaks)."""
    return RunOptions(levels=study.levels, ratio=study.ratio, to_tolerance=False, sensitivity=study.sensitivity,
                      formula_loads=False, loads=tuple(loads) if len(loads) > 1 else (),
                      memory_limit_gb=study.memory_limit_gb, outputs=Outputs(fields=False, mesh=False))


@dataclass(frozen=True)
class Task:
    """One geometry and material of the grid, with every load it is asked at."""

    key: str
    params: dict  # the swept non-load parameters, name -> value
    case: Case | None  # None: invalid (see note)
    loads: tuple[float, ...]
    note: str = ""


def plan(study: Study) -> list[Task]:
    """The grid's tasks: the product of the study's axes, each at every load of its loads
    (or the case's own load); with ``sizes``, that grid for every hook number (each at its
    own rated load unless loads are given). Whether each variant varies its assumed inputs
    is part of its key, so a study without it is not taken for one with it."""
    size, case_file, base, axes, loads = study.size, study.case_file, study.base, study.axes, study.loads
    levels, ratio, sizes, sensitivity = study.levels, study.ratio, study.sizes, study.sensitivity
    names = list(axes)
    tasks = []
    for hook, combo in itertools.product(sizes or [size], itertools.product(*(axes[n] for n in names))):
        params = dict(zip(names, combo), **({"size": hook} if sizes else {}))
        over = dict(base, **{k: v for k, v in params.items() if k != "size"})
        try:
            case = resolve(hook, case_file, over)
            qs = tuple(loads) or (case.load_N,)
            for q in qs:
                resolve(hook, case_file, dict(over, load_N=q))
            note = ""
        except InputError as exc:
            case, qs, note = None, tuple(loads), " ".join(str(exc).split())
        ident = {"case": None if case is None else case.as_dict(), "loads": qs, "levels": levels,
                 "ratio": ratio, "params": params, "code": code_key(), **({"sensitivity": True} if sensitivity else {})}
        key = hashlib.sha1(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()[:12]
        tasks.append(Task(key=key, params=params, case=case, loads=qs, note=note))
    valid = [t.case for t in tasks if t.case is not None]
    if not valid:  # refused before the output folder is touched: nothing to analyse
        if len({t.note for t in tasks}) == 1:  # not the variants: an input they all share is wrong
            raise InputError(tasks[0].note)
        raise InputError(f"sweep: every variant is invalid; the first: {tasks[0].note}")
    check_options(valid[0], variant_options(study, tuple(study.loads)), "sweep", study.given)
    if study.screen and valid[0].mesh_factor > SCREEN_MAX_MESH_FACTOR:
        raise InputError(f"screen: screening's bands were measured at mesh factor {SCREEN_MAX_MESH_FACTOR:g} or finer "
                         f"and do not hold at {valid[0].mesh_factor:g}; give --mesh-factor "
                         f"{SCREEN_MAX_MESH_FACTOR:g} or leave screening off")
    return tasks


def read_study(path: Path) -> dict:
    """A study file (TOML, e.g. cases/sweep-rf.toml): its [sweep] table with ``size`` or
    ``case``, ``dims`` (NAME = "START:STOP:COUNT" or "a,b,c"), ``load``, ``levels``,
    ``ratio``, ``mesh_factor``, ``out``, ``screen`` (true: a screened study). Read by the guarded reader case files share
    (pipeline.inputs.tomlfile). A relative ``case`` or ``out`` is taken from the study
    file's folder, as a Path: the file means the same wherever the command starts."""
    from geometry.table import Dimensions
    data = read_toml(path, "study")
    s = data.get("sweep")
    if not isinstance(s, dict) or set(data) != {"sweep"}:
        extra = ", ".join(sorted(set(data) - {"sweep"}))
        raise InputError(f"study: {path} holds one [sweep] table and nothing else"
                         + (f" (found {extra}; material and mesh options go in a case file, case = ...)"
                            if extra else ""))
    for key, value in s.items():
        types = STUDY_KEYS.get(key)
        if types is None:
            raise InputError(f"sweep.{key}: unknown key in {path}; known: {', '.join(STUDY_KEYS)}")
        if (isinstance(value, bool) and bool not in types) or not isinstance(value, types):
            raise InputError(f"sweep.{key}: expected {' or '.join(TOML_NAMES[t] for t in types)} in {path}, "
                             f"got {value!r}")
    names = list(Dimensions.__dataclass_fields__)
    if "load" in s:  # loads, like a dimension's values, may be a TOML array of numbers
        s = dict(s, load=_array_as_list(s["load"], "sweep.load", path))
    dims = {}
    for name, values in s.get("dims", {}).items():
        if name not in names:
            raise InputError(f"sweep.dims.{name}: unknown dimension in {path}; known: {', '.join(names)}")
        values = _array_as_list(values, f"sweep.dims.{name}", path)
        if isinstance(values, bool) or not isinstance(values, (str, int, float)):
            raise InputError(f"sweep.dims.{name}: expected \"START:STOP:COUNT\", \"v1,v2,...\", an array of "
                             f"numbers or a number in {path}, got {values!r}")
        dims[name] = values
    for key in ("case", "out"):
        if key in s and not s[key].strip():
            raise InputError(f"sweep.{key}: an empty path in {path}")
    paths = {k: Path(path).parent / Path(s[k]).expanduser() for k in ("case", "out") if k in s}
    return dict(s, **paths, **({"dims": dims} if "dims" in s else {}))


def _array_as_list(values, name: str, path: Path):
    """A TOML array of numbers as the list text "a,b,c" (pipeline.inputs.valuelist reads it);
    anything else as it is, except an array holding something other than numbers."""
    if not isinstance(values, list):
        return values
    if values and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return ",".join(repr(v) for v in values)
    raise InputError(f"{name}: expected an array of numbers in {path}, got {values!r}")


def variant_folder(out: Path, key: str) -> Path:
    """Where task ``key`` of the study in ``out`` writes its run (its results.json inside)."""
    return out / "variants" / key


def failure_file(out: Path, key: str) -> Path:
    """Where task ``key`` of the study in ``out`` writes why it failed, instead of a run."""
    return out / "variants" / f"{key}.failed.json"


def earlier_variants(out: Path, keys: set[str]) -> list[Path]:
    """The results in the study folder ``out`` of variants that are not among ``keys``:
    what a run of the study with other inputs or older code left (a variant's key hashes
    both). Only what a variant writes is named: a folder with the tool's own marker
    (pipeline.runtime.folders.marker_data: an empty or foreign marker is a user's), or a
    ``<key>.failed.json`` that matches its checksum."""
    from pipeline.runtime.folders import marker_data
    from pipeline.study.manifest import VariantFault, read_failure
    found = []
    folder = out / "variants"
    for p in sorted(folder.iterdir()) if folder.is_dir() else []:
        if p.is_dir() and not p.is_symlink() and p.name not in keys and marker_data(p) is not None:
            found.append(p)
        elif p.is_file() and p.name.endswith(".failed.json") and p.name.removesuffix(".failed.json") not in keys:
            try:
                read_failure(p)
            except VariantFault:
                continue  # not a note this tool wrote (or one changed since): kept
            found.append(p)
    return found
