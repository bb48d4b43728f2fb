"""The report's title block from its three sources (pipeline/inputs/document.py,
pipeline/inputs/case.py resolve): the defaults file, then the case file's [document],
then --document, each field taken from the last that gives it; a field none gives stays
blank. The expected fields are the files' own text."""
from __future__ import annotations

import re

import pytest

from pipeline.errors import InputError
from pipeline.inputs.case import resolve
from pipeline.inputs.document import defaults_file


def test_the_defaults_file_fills_what_the_case_file_and_the_options_leave(tmp_path, monkeypatch):
    defaults = tmp_path / "document.toml"
    defaults.write_text('[document]\nauthor = "A. Default"\nchecker = "C. Default"\npart = "Default part"\n')
    case = tmp_path / "05.toml"
    case.write_text('size = "05"\n[document]\npart = "From the case"\nnumber = "CN-1"\n')
    monkeypatch.setenv("CROSSHEAD_DOCUMENT", str(defaults))
    doc = resolve(None, case, {"document.checker": "C. Option"}).document
    assert doc.as_dict() == {"part": "From the case", "number": "CN-1", "revision": None, "author": "A. Default",
                             "checker": "C. Option"}
    assert resolve("05").document.author == "A. Default"
    # No number of the analysis depends on it: the case is the same without the file.
    monkeypatch.setenv("CROSSHEAD_DOCUMENT", "")
    assert resolve("05").document.author is None and resolve("05").as_dict() == resolve("05").as_dict()


def test_the_defaults_file_is_found_in_the_user_s_configuration_folder(tmp_path, monkeypatch):
    monkeypatch.delenv("CROSSHEAD_DOCUMENT", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert defaults_file() is None  # none there: no file, no error
    (tmp_path / "crosshead").mkdir()
    (tmp_path / "crosshead" / "document.toml").write_text('[document]\nrevision = "B"\n')
    assert defaults_file() == tmp_path / "crosshead" / "document.toml"
    assert resolve("05").document.revision == "B"


@pytest.mark.parametrize("text,words", [('author = "x"\n', "one [document] table"),
                                        ('[document]\nwriter = "x"\n', "document.writer: unknown key"),
                                        ('[document]\nrevision = 2\n', "document.revision: expected str"),
                                        ("[document\n", "not valid TOML")])
def test_a_bad_defaults_file_is_one_line_naming_it(tmp_path, monkeypatch, text, words):
    bad = tmp_path / "document.toml"
    bad.write_text(text)
    monkeypatch.setenv("CROSSHEAD_DOCUMENT", str(bad))
    with pytest.raises(InputError, match=re.escape(words)) as err:
        resolve("05")
    assert str(bad) in str(err.value) and "\n" not in str(err.value)
