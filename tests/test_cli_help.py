"""Every verb's --help has a description, every option a help text, and each verb an example that parses."""

from __future__ import annotations

import argparse
import shlex

import pytest

from parsel_core.cli import build_parser, main


def verbs() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


@pytest.mark.parametrize("name", sorted(verbs()))
def test_help_has_a_description_options_with_help_and_examples(name, capsys):
    with pytest.raises(SystemExit) as done:
        main([name, "--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    parser = verbs()[name]
    assert parser.description and len(parser.description) > 40, f"{name}: no description"
    assert parser.description.split()[0] in text
    for action in parser._actions:
        if not isinstance(action, argparse._HelpAction) and action.help != argparse.SUPPRESS:
            assert action.help, f"{name}: {action.option_strings or action.dest} has no help"
    assert "examples:\n  parsel " + name in text, f"{name}: no example"
    # every example parses (a pipe or && starts another command)
    examples = [line.strip() for line in parser.epilog.splitlines()[1:]]
    for example in examples:
        for command in example.split(" | ")[0].split(" && "):
            words = shlex.split(command)
            if words[0] == "parsel":
                build_parser().parse_args(words[1:])


def test_top_level_help_does_not_call_edit_expert_mode(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "edit" in text and "expert mode: propagate" not in text and "examples:\n  parsel edit chair" in text
    # the bundled plugins' verbs are described too, without importing them
    for verb in ("view", "render", "fit", "eval", "batch"):
        if verb in verbs():
            line = text.split(f"\n    {verb}", 1)[1].split("\n    ", 1)[0]
            assert "--help says more" not in line and len(line.split()) > 5, line


#: Every flag that more than one verb lists -> what its help says on each of them.
MEANINGS = {
    "--api-base": "OpenAI-compatible server",
    "--backend": "CAS backend",
    "--break": "relation",
    "--cache": "reply cache directory",
    "--count": "number of",
    "-n": "number of",
    "--force": "OUTDIR",
    "--format": "for -o -",
    "--json": "JSON|machine-readable",
    "--model": "model name",
    "--output": "^output (file|folder)",
    "-o": "^output (file|folder)",
    "--provider": "language-model provider",
    "--quiet": "print results only",
    "-q": "print results only",
    "--samples": "majority voting",  # check's parameter values are --steps
    "--seed": "seed op",  # fit's random seed is --rng-seed
    "--set": "parameter",
    "--shape": "example name",
    "--verbose": "also (print|log)",
    "-v": "also (print|log)",
    "--workers": "local worker processes",
}


def test_a_flag_name_means_one_thing_across_verbs():
    """A flag listed by several verbs says the same thing on each (hidden old spellings aside)."""
    import re

    uses: dict[str, list[tuple[str, str]]] = {}
    for name, parser in verbs().items():
        for action in parser._actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
                continue
            for flag in action.option_strings:
                uses.setdefault(flag, []).append((name, action.help))
    shared = {flag: helps for flag, helps in uses.items() if len(helps) > 1}
    assert set(shared) <= set(MEANINGS), f"flags shared by several verbs without a stated meaning: " \
                                         f"{sorted(set(shared) - set(MEANINGS))}"
    for flag, helps in shared.items():
        for verb, text in helps:
            assert re.search(MEANINGS[flag], text), f"{verb} {flag}: {text!r} does not mean {MEANINGS[flag]!r}"
    assert {verb for verb, _ in uses["--set"]} >= {"evaluate", "apply"}


def numeric_options():
    """(verb, flag, type) for every option that takes a number, plugins' verbs included."""
    found = []
    for name, parser in sorted(verbs().items()):
        for action in parser._actions:
            if action.option_strings and action.type not in (None, str):
                found.append((name, " ".join(action.option_strings), action.type))
    return found


@pytest.mark.parametrize("verb, flag, kind", numeric_options(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_numeric_option_is_checked_in_one_line(verb, flag, kind, capsys):
    """A number that does not parse, or one below or above the option's range, is one line and exit status 2."""
    assert kind not in (int, float), f"{verb} {flag}: a plain {kind.__name__} (use bounded_int / bounded_float)"
    lo, hi = kind.bounds
    bad = ["many", "nan", str(lo - 1)] + ([str(hi + 1)] if hi is not None else [])
    for text in bad:
        assert main([verb, flag.split()[-1], text]) == 2, (verb, flag, text)
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("parsel: error: ") and any(f in err for f in flag.split()), err


def test_the_numeric_options_include_the_plugins_verbs():
    flags = {(verb, flag.split()[-1]) for verb, flag, _ in numeric_options()}
    assert {("edit", "--timeout"), ("edit", "--retries"), ("edit", "--tau"), ("apply", "--sweep"),
            ("check", "--steps"), ("proxydural", "--count")} <= flags
    for verb, flag in (("render", "--frames"), ("fit", "--starts"), ("fit", "--rng-seed"), ("view", "--port"),
                       ("batch", "--workers"), ("eval", "--workers")):
        assert verb not in verbs() or (verb, flag) in flags, (verb, flag)
