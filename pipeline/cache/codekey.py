"""One key for "this code": a hash of every source file that can change a result.

Every cache entry and every study variant is keyed with it, so that nothing computed by
other code is ever taken as this code's answer. It covers every Python file of the
``pipeline`` and ``geometry`` packages, found recursively (a file moved into a subfolder,
or added there, changes the key), the size tables they read, and the versions of the form
compiler chain (UFL, FFCx, Basix, DOLFINx) that turn the forms into the compiled kernels.
"""
from __future__ import annotations

import functools
import hashlib
from importlib import metadata
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[2]
PACKAGES = ("pipeline", "geometry")
DATA_SUFFIXES = (".py", ".csv")
FORM_CHAIN = ("fenics-ufl", "fenics-ffcx", "fenics-basix", "fenics-dolfinx")


def source_files(root: Path = REPOSITORY) -> list[Path]:
    """Every file under the packages in ``root`` whose content can change a result: the
    Python sources and the tables (.csv), recursively, in a fixed order."""
    return sorted(f for package in PACKAGES for f in (root / package).rglob("*")
                  if f.is_file() and f.suffix in DATA_SUFFIXES and "__pycache__" not in f.parts)


def _version(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "absent"


@functools.cache
def code_key(root: Path = REPOSITORY) -> str:
    """A hex digest of the sources under ``root`` (paths and contents) and of the form
    compiler chain's versions. Read once per process: the sources do not change while it runs."""
    h = hashlib.sha256()
    for f in source_files(root):
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    for name in FORM_CHAIN:
        h.update(f"{name}={_version(name)}\0".encode())
    return h.hexdigest()
