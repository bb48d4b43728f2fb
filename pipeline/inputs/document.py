"""The title block's defaults: the fields of a report's title block (part, number, revision,
author, checker) that an engineer fills once for every run, in a TOML file with a
``[document]`` table like a case file's. A case file's ``[document]`` overrides them, and
``run --document FIELD=TEXT`` both. The file is ``$CROSSHEAD_DOCUMENT`` when that is set
(empty: none), else ``$XDG_CONFIG_HOME/crosshead/document.toml`` (``~/.config/crosshead/
document.toml``) when it exists. It sets no number of the analysis.
"""
from __future__ import annotations

import os
from pathlib import Path

from pipeline.errors import InputError
from pipeline.inputs.tomlfile import read_toml

ENV = "CROSSHEAD_DOCUMENT"
KEYS = ("part", "number", "revision", "author", "checker")  # pipeline.inputs.case.DOCUMENT_KEYS


def defaults_file() -> Path | None:
    """The title block's defaults file the run reads, or None: $CROSSHEAD_DOCUMENT (empty:
    none), else the user's configuration folder's crosshead/document.toml if it exists."""
    if ENV in os.environ:
        return Path(os.environ[ENV]).expanduser() if os.environ[ENV] else None
    config = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    path = config / "crosshead" / "document.toml"
    return path if path.is_file() else None


def document_defaults() -> dict[str, str]:
    """The defaults file's fields as a case's keys ({"document.author": "A. Engineer"});
    empty without a file. InputError (exit 2) names the file when it cannot be read or
    holds anything but a [document] table of text fields."""
    path = defaults_file()
    if path is None:
        return {}
    data = read_toml(path, f"document defaults ({ENV})")
    table = data.get("document")
    if set(data) != {"document"} or not isinstance(table, dict):
        raise InputError(f"document defaults: {path} must hold one [document] table (keys {', '.join(KEYS)})")
    for key, value in table.items():
        if key not in KEYS:
            raise InputError(f"document.{key}: unknown key in {path}; known in [document]: {', '.join(KEYS)}")
        if not isinstance(value, str):
            raise InputError(f"document.{key}: expected str, got {value!r} in {path}")
    return {f"document.{k}": v for k, v in table.items()}
