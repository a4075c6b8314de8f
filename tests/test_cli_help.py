"""What a newcomer reads first: every subcommand's ``--help`` (a description, the defaults),
and ``nrmlc params``, the table of the tracker's parameters.

``nrmlc.tracker.params.describe_parameters`` is the tracker's own list; the tests that
check the table's layout give ``nrmlc params`` a small stand-in of it, so that they pin
the command, not the parameters of the day.
"""
from __future__ import annotations

import argparse

import pytest

from nrmlc import cli
from nrmlc.tracker import params as tracker_params

#: Every subcommand ``nrmlc`` has.
COMMANDS = ("track", "list", "synth", "params", "benchmark", "evaluate")


def test_every_command_is_covered():
    choices = next(action for action in cli.build_parser()._actions
                   if isinstance(action, argparse._SubParsersAction)).choices
    assert set(choices) == set(COMMANDS)


def _help(command: str, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        cli.main([command, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


def _option_help(text: str, option: str) -> str:
    """The help entry of ``option`` in a ``--help`` text, as one line."""
    entry = text.split(f"\n  {option}", 1)[1]
    entry = entry.split("\n  -", 1)[0].split("\n\n", 1)[0]
    return " ".join(entry.split())


def _described_defaults(command: str) -> list[str]:
    """The options of ``command`` whose default is worth naming (not None, False or empty)."""
    parser = next(action for action in cli.build_parser()._actions
                  if isinstance(action, argparse._SubParsersAction)).choices[command]
    return [action.option_strings[-1] for action in parser._actions
            if action.option_strings and not (action.default is None or action.default is False
                                              or action.default == [] or action.default is argparse.SUPPRESS)]


@pytest.mark.parametrize("command", COMMANDS)
def test_help_has_a_description_and_names_the_defaults(command, capsys):
    text = _help(command, capsys)
    usage, description = text.split("\n\n")[:2]
    assert usage.startswith("usage:")
    # A paragraph, not an argument list: several words, a full stop.
    assert not description.lstrip().startswith(("positional arguments", "options")), text
    assert len(description.split()) >= 12 and "." in description, description
    for option in _described_defaults(command):
        entry = _option_help(text, option)
        assert "default" in entry, f"{command} {option}: no default in its help:\n{entry}"
    if command != "list":  # list's only argument is the folder, which has no default
        assert "default" in text


@pytest.mark.parametrize("command", ["synth", "params", "benchmark"])
def test_options_with_a_default_say_it(command, capsys):
    text = _help(command, capsys)
    assert "(default: " in text or "(default " in text


@pytest.mark.parametrize("command", ["track", "benchmark"])
def test_param_option_points_to_nrmlc_params(command, capsys):
    assert "nrmlc params" in _option_help(_help(command, capsys), "--param")


def test_a_none_or_flag_default_is_not_printed():
    parser = argparse.ArgumentParser(formatter_class=cli.HelpFormatter)
    parser.add_argument("--flag", action="store_true", help="a flag")
    parser.add_argument("--maybe", help="optional")
    parser.add_argument("--many", action="append", default=[], help="repeatable")
    parser.add_argument("--count", type=int, default=0, help="a count")
    parser.add_argument("--seed", type=int, default=3, help="a seed (default 3)")
    text = parser.format_help()
    assert "(default: None)" not in text and "(default: False)" not in text and "(default: [])" not in text
    assert "a count (default: 0)" in text
    assert text.count("default") == 2  # the count's, and the seed's own wording once


# ------------------------------------------------------------------ nrmlc params
def _stand_in(preset: str = "default") -> list[dict]:
    """A describe_parameters of three parameters in two groups; 'paper' changes one."""
    rows = [
        dict(name="n_particles", group="motion", default=450 if preset == "default" else 600,
             range="1..100000", meaning="particles per frame"),
        dict(name="motion_sigmas", group="motion", default=(2.0, 2.0, 0.01, 0.0, 0.005, 0.0),
             range="each >= 0", meaning="std of the motion model"),
        dict(name="occlusion_detection", group="updates", default=True, range="true, false",
             meaning="hold the templates while the target is occluded"),
    ]
    return rows


@pytest.fixture
def stand_in(monkeypatch):
    monkeypatch.setattr(tracker_params, "describe_parameters", _stand_in, raising=False)


def test_params_prints_an_aligned_table_grouped_by_group(stand_in, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # a wide terminal: one line per parameter
    assert cli.main(["params"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("Tracker parameters, preset 'default'")
    assert "motion:" in lines and "updates:" in lines
    assert lines.index("motion:") < lines.index("updates:")
    rows = {line.split()[0]: line for line in lines if line.startswith("  ") and not line.lstrip().startswith("name")}
    assert set(rows) == {"n_particles", "motion_sigmas", "occlusion_detection"}
    assert "2,2,0.01,0,0.005,0" in rows["motion_sigmas"]  # as --param takes it
    assert " true " in rows["occlusion_detection"]
    # aligned: every column starts at the same place on every row, across the groups
    for column in ("1..100000", "each >= 0", "true, false"):
        starts = {line.index(column) for line in rows.values() if column in line}
        assert len(starts) == 1
    assert len({line.index(row["meaning"]) for row, line in zip(_stand_in(), rows.values())}) == 1
    assert "*" not in out


def test_params_preset_marks_what_differs_from_the_default(stand_in, capsys):
    assert cli.main(["params", "--preset", "paper"]) == 0
    out = capsys.readouterr().out
    assert "preset 'paper'" in out
    row = next(line for line in out.splitlines() if line.lstrip().startswith("n_particles"))
    assert "600*" in row
    assert "differs from the 'default' preset (1 of 3 parameters)" in out


def test_params_unknown_preset_is_a_usage_error(stand_in, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(["params", "--preset", "nope"])
    assert exit_.value.code == 2 and "invalid choice" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(tracker_params, "describe_parameters"),
                    reason="nrmlc.tracker.params.describe_parameters is not there yet")
def test_params_lists_every_tracker_parameter(capsys):
    import dataclasses

    assert cli.main(["params"]) == 0
    out = capsys.readouterr().out
    listed = {line.split()[0] for line in out.splitlines() if line.startswith("  ")}
    assert {field.name for field in dataclasses.fields(tracker_params.TrackerParams)} <= listed | {"name"}


def test_params_wraps_long_meanings_under_their_column():
    rows = _stand_in()
    rows[0] = dict(rows[0], meaning="particles per frame, " * 8)
    lines = cli.format_parameter_table(rows, width=100)
    start = lines[2].index("meaning")
    first = next(i for i, line in enumerate(lines) if line.lstrip().startswith("n_particles"))
    assert all(len(line) <= 100 for line in lines[2:])
    assert len([line for line in lines if line.startswith(" " * start)]) >= 3  # 168 characters in 44-wide lines
    assert lines[first + 1].startswith(" " * start) and lines[first + 1][start] != " "
    assert cli.format_parameter_table(rows)[first].count("particles per frame") == 8  # no width: one line
