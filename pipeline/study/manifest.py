"""A design study's variants carry checksums of the files they wrote, so that a study
(and the size summary) never takes a file edited or cut short after its run for that
run's result.

A finished variant's folder ``variants/<key>/`` holds ``manifest.json``: the SHA-256 of
every file the run wrote (results.json, the results marker), written last and whole
(pipeline.runtime.atomicfile), after the run's folder is in place. A folder without it
is a run that stopped before it ended. A failed variant's ``<key>.failed.json`` carries
the SHA-256 of its own content. Nothing here needs MPI or DOLFINx: the size summary
reads it too.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from pipeline.runtime.atomicfile import write_text

MANIFEST = "manifest.json"  # in a finished variant's folder, beside the files it names
RESULTS = "results.json"  # the file a study reads of each variant: the manifest must name it
CHUNK = 1 << 20  # bytes hashed at a time


class VariantFault(ValueError):
    """A variant's files do not match their checksums; the message says which and how, as
    "results.json does not match its checksum"."""


def sha256_of(path: Path) -> str:
    """The SHA-256 of the file ``path``'s bytes, as hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(CHUNK):
            h.update(chunk)
    return h.hexdigest()


def write_manifest(folder: Path) -> None:
    """Write ``folder``'s manifest: the SHA-256 of every file in it (the run's files),
    whole or not at all. Called once the run's folder is in place: the manifest is the
    last thing a finished variant writes."""
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.is_symlink() and p.name != MANIFEST)
    sums = {p.name: sha256_of(p) for p in files}
    write_text(folder / MANIFEST, json.dumps({"sha256": sums}, indent=1, sort_keys=True) + "\n")


def folder_fault(folder: Path) -> str | None:
    """Why the files of the variant folder ``folder`` cannot be taken as its run wrote
    them, or None when every file its manifest names is there with its checksum (and the
    manifest names results.json)."""
    if not (folder / RESULTS).is_file():
        return f"{RESULTS} is missing"
    try:
        sums = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))["sha256"]
    except FileNotFoundError:
        return f"{RESULTS} has no checksum (its run did not end, or an older version wrote it)"
    except (OSError, ValueError, KeyError, TypeError):
        return f"its checksums ({MANIFEST}) cannot be read"
    if not isinstance(sums, dict) or RESULTS not in sums:
        return f"its checksums ({MANIFEST}) do not name {RESULTS}"
    for name, digest in sorted(sums.items(), key=lambda kv: kv[0] != RESULTS):  # results.json first
        path = folder / str(name)
        if "/" in str(name) or not path.is_file() or path.is_symlink():
            return f"{name} is missing"
        try:
            if sha256_of(path) != digest:
                return f"{name} does not match its checksum"
        except OSError as exc:
            return f"{name} cannot be read ({exc.strerror or exc})"
    return None


def read_results(folder: Path) -> dict[str, Any]:
    """The variant's results.json, once its files match their checksums; raises
    VariantFault saying why not."""
    why = folder_fault(folder)
    if why is None:
        try:
            return json.loads((folder / RESULTS).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:  # written so by its run: its checksum matches
            why = f"{RESULTS} cannot be read ({type(exc).__name__}: {exc})"
    raise VariantFault(why)


def _failure_digest(note: dict[str, Any]) -> str:
    """The SHA-256 of a failure note's content (its keys sorted, the checksum left out)."""
    body = {k: v for k, v in note.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode("utf-8")).hexdigest()


def write_failure(path: Path, note: dict[str, Any]) -> None:
    """Write a failed variant's ``note`` (why, its size and inputs) to ``path`` with the
    checksum of its content, whole or not at all."""
    write_text(path, json.dumps(dict(note, sha256=_failure_digest(note))) + "\n")


def read_failure(path: Path) -> dict[str, Any]:
    """A failed variant's note (without its checksum) once it matches it; raises
    VariantFault saying why not."""
    try:
        note = json.loads(path.read_text(encoding="utf-8"))
        ok = isinstance(note, dict) and note.get("sha256") == _failure_digest(note)
    except (OSError, ValueError) as exc:
        raise VariantFault(f"{path.name} cannot be read ({type(exc).__name__})") from None
    if not ok:
        raise VariantFault(f"{path.name} does not match its checksum")
    return {k: v for k, v in note.items() if k != "sha256"}


def failure_fault(path: Path) -> str | None:
    """Why the failure note ``path`` cannot be taken as its run wrote it, or None."""
    try:
        read_failure(path)
    except VariantFault as exc:
        return str(exc)
    return None
