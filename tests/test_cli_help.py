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
    assert "edit" in text and "expert mode: propagate" not in text and "example: parsel edit chair" in text


def test_a_flag_name_means_one_thing_across_verbs():
    """--samples is the number of model replies per prompt wherever it is listed (check has --steps)."""
    meanings = {}
    for name, parser in verbs().items():
        for action in parser._actions:
            if "--samples" in action.option_strings and action.help != argparse.SUPPRESS:
                meanings[name] = action.help
    assert meanings and all("majority voting" in text for text in meanings.values()), meanings
