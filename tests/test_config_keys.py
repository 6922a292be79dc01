"""Unknown settings are warned about with the closest known key; a bad backend name says where it came from."""

from __future__ import annotations

import subprocess
import sys

import pytest

from parsel_core import config
from parsel_core.errors import ParselError
from parsel_core.plugins import get_cas_backend


def test_a_misspelled_key_is_warned_about_once_with_the_closest_known_key(tmp_path, monkeypatch):
    path = tmp_path / "parsel.toml"
    path.write_text('[parsel]\nrelation_tolerence = 0.02\ncolour = "red"\ncas_backend = "sympy"\n')
    monkeypatch.setenv("PARSEL_CONFIG", str(path))
    monkeypatch.setattr(config, "_warned", set())
    with pytest.warns(config.ConfigWarning) as caught:
        settings = config.load_settings()
    assert settings["cas_backend"] == "sympy"
    messages = sorted(str(w.message) for w in caught)
    assert messages == [
        f"{path}: [parsel] 'colour' is not a setting parsel reads and is ignored (known: cas_backend, "
        "relation_tolerance, and the max_* limits in the README)",
        f"{path}: [parsel] 'relation_tolerence' is not a setting parsel reads and is ignored; did you mean "
        "'relation_tolerance'?",
    ]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config.load_settings()  # once only


def test_the_cli_prints_the_warning_in_one_line(tmp_path):
    path = tmp_path / "parsel.toml"
    path.write_text("[parsel]\ncas_backnd = 'sympy'\n")
    program = tmp_path / "p.parsel"
    program.write_text("param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=x)\n")
    done = subprocess.run([sys.executable, "-m", "parsel_core.cli", "evaluate", "tiny_table", str(program)],
                          capture_output=True, text=True, env={**__import__("os").environ, "PARSEL_CONFIG": str(path)},
                          timeout=120)
    assert done.returncode == 0
    assert done.stderr == (f"parsel: warning: {path}: [parsel] 'cas_backnd' is not a setting parsel reads and is "
                           "ignored; did you mean 'cas_backend'?\n")


def test_a_bad_backend_name_names_its_source(tmp_path, monkeypatch):
    monkeypatch.setenv("PARSEL_CAS_BACKEND", "sympyy")
    with pytest.raises(ParselError, match=r"unknown CAS backend 'sympyy' \(from \$PARSEL_CAS_BACKEND\) \(installed: "):
        get_cas_backend()
    monkeypatch.delenv("PARSEL_CAS_BACKEND")
    path = tmp_path / "parsel.toml"
    path.write_text('[parsel]\ncas_backend = "maxima"\n')
    monkeypatch.setenv("PARSEL_CONFIG", str(path))
    with pytest.raises(ParselError, match=rf"'maxima' \(from cas_backend in {path}\)"):
        get_cas_backend()


def test_limits_are_settings_too(tmp_path, monkeypatch):
    path = tmp_path / "parsel.toml"
    path.write_text("[parsel]\nmax_parts = 50\nmax_part = 3\n")
    monkeypatch.setenv("PARSEL_CONFIG", str(path))
    monkeypatch.setattr(config, "_warned", set())
    with pytest.warns(config.ConfigWarning) as caught:
        config.load_settings()
    assert [str(w.message).split("ignored")[1] for w in caught] == ["; did you mean 'max_parts'?"]
    assert config.limit("max_parts") == 50


def test_keys_and_tables_outside_the_parsel_table_are_warned_about(tmp_path, monkeypatch):
    """``relation_tolerence = ...`` above ``[parsel]``, or a ``[parsl]`` table, is never read: said so, once."""
    path = tmp_path / "parsel.toml"
    path.write_text('relation_tolerence = 0.02\ncas_backend = "sympy"\n[parsl]\nmax_parts = 5\n[parsel]\n'
                    'max_sweep = 7\n')
    monkeypatch.setenv("PARSEL_CONFIG", str(path))
    monkeypatch.setattr(config, "_warned", set())
    with pytest.warns(config.ConfigWarning) as caught:
        settings = config.load_settings()
    assert settings == {"max_sweep": 7}
    assert sorted(str(w.message).removeprefix(f"{path}: ") for w in caught) == [
        "'cas_backend' is outside the [parsel] table and is ignored; did you mean 'cas_backend' in the [parsel] "
        "table?",
        "'relation_tolerence' is outside the [parsel] table and is ignored; did you mean 'relation_tolerance' in "
        "the [parsel] table?",
        "table [parsl] is not read and is ignored; did you mean [parsel]?",
    ]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config.load_settings()  # once only


def test_a_misspelled_key_reaches_the_command_line_as_one_line(tmp_path):
    """The issue's case: relation_tolerence in parsel.toml, then a command that reads the settings."""
    (tmp_path / "parsel.toml").write_text("relation_tolerence = 0.02\n")
    program = tmp_path / "p.parsel"
    program.write_text("param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=x)\n")
    env = {k: v for k, v in __import__("os").environ.items() if k != "PARSEL_CONFIG"}
    done = subprocess.run([sys.executable, "-m", "parsel_core.cli", "check", "tiny_table", str(program)],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ("parsel: warning: parsel.toml: 'relation_tolerence' is outside the [parsel] table and is "
                           "ignored; did you mean 'relation_tolerance' in the [parsel] table?\n")


def test_parsel_toml_is_parsed_once_until_it_changes(tmp_path, monkeypatch):
    """Limits are read where the numbers they bound are, so reading settings must be cheap;
    an edited file (even one of the same size, within the same clock tick) is read anew."""
    import tomllib

    path = tmp_path / "parsel.toml"
    path.write_text(f"# {tmp_path}\n[parsel]\nmax_ops = 3\n")
    monkeypatch.setenv("PARSEL_CONFIG", str(path))
    parses = []
    original = tomllib.loads
    monkeypatch.setattr(tomllib, "loads", lambda text: parses.append(text) or original(text))
    assert [config.limit("max_ops") for _ in range(5)] == [3] * 5
    assert len(parses) == 1
    path.write_text(f"# {tmp_path}\n[parsel]\nmax_ops = 4\n")
    assert config.limit("max_ops") == 4
    settings = config.load_settings()
    settings["max_ops"] = 9  # a caller's copy
    assert config.limit("max_ops") == 4
    assert len(parses) == 2
