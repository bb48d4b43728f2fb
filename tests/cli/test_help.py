"""The help says what the command does: every default a help text names is the one the
command uses (the parser's own default, the Case's field default, or a study's default)."""
import dataclasses
import re

import pytest

from pipeline.cli import SWEEP_DEFAULTS, make_parser
from pipeline.inputs.case import Case

NUMBER = re.compile(r"\(default:? ([-+0-9.e]+)[;,)]")


def _subcommands():
    parser = make_parser()
    sub = next(a for a in parser._actions if isinstance(a.choices, dict))
    return sub.choices.items()


def _used_default(command: str, action):
    """The value the command uses when the option is not given."""
    if action.default is not None:
        return action.default
    fields = {f.name: f.default for f in dataclasses.fields(Case)}
    if action.dest in fields:
        return fields[action.dest]
    if command == "sweep" and action.dest in SWEEP_DEFAULTS:
        return SWEEP_DEFAULTS[action.dest]
    raise AssertionError(f"{command} {action.option_strings}: the help names a default the code does not hold")


@pytest.mark.parametrize("command,sub", list(_subcommands()))
def test_every_numeric_default_in_help_is_the_one_used(command, sub):
    checked = 0
    for action in sub._actions:
        m = NUMBER.search(action.help or "")
        if m is None:
            continue
        assert float(m.group(1)) == pytest.approx(float(_used_default(command, action))), (command, action.dest)
        checked += 1
    assert checked >= 5, command


def test_the_output_folder_default_named_in_help_is_the_one_written(tmp_path, monkeypatch):
    """--out's help names the folder each command writes without it."""
    from pipeline.runtime.folders import default_out
    helps = {c: next(a.help for a in sub._actions if a.dest == "out") for c, sub in _subcommands()}
    assert "results/<case name>)" in helps["run"] and str(default_out("05")).endswith("results/05")
    assert "results/<case name>-converge" in helps["converge"]
    assert "results/sweep-<size" in helps["sweep"]
