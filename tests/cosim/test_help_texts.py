"""What a user learns from ``--help`` alone: each option says what it is, its unit, its
default and the values it takes, and says nothing the command does not do."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path

import pytest

from cosim.cli import build_parser, main


def _parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """``parser`` and every command's and analysis's parser under it."""
    yield parser
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        for sub in dict.fromkeys(action.choices.values()):
            yield from _parsers(sub)


def _parser(*path: str) -> argparse.ArgumentParser:
    """The parser of ``auv-cosim PATH...`` (``"analyze", "sweep"``)."""
    parser = build_parser()
    for name in path:
        (action,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[name]
    return parser


def _option_help(parser: argparse.ArgumentParser, option: str) -> str:
    """The help text of ``option`` as ``--help`` prints it, on one line."""
    (action,) = (a for a in parser._actions if option in a.option_strings)
    formatter = parser._get_formatter()
    return " ".join(formatter._expand_help(action).split())


def _listed(parser: argparse.ArgumentParser, command: str) -> str:
    """The one line ``parser``'s help gives ``command``."""
    (action,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    (choice,) = (c for c in action._choices_actions if c.dest == command)
    return str(choice.help)


def test_the_command_list_names_every_analysis() -> None:
    """``auv-cosim --help`` listed ``analyze`` as "equilibria, continuation sweeps, phase
    portraits": a user looking for the LQR loop's margins did not learn there that
    ``analyze margins`` gives them."""
    listed = _listed(build_parser(), "analyze")
    said = {"equilibria": "equilibria", "sweep": "continuation", "phase-portrait": "phase portrait",
            "margins": "margins"}  # fmt: skip
    assert set(said) == set(_parser("analyze")._subparsers._group_actions[0].choices)
    assert all(word in listed for word in said.values()), listed


def test_a_required_argument_claims_no_default() -> None:
    """``report --help`` said RUN_DIR was "runs/<scenario-id> by default", but the command
    takes no default: ``auv-cosim report`` alone is a usage error."""
    claims = []
    for parser in _parsers(build_parser()):
        for action in parser._actions:
            if action.option_strings or action.nargs is not None or action.help is None:
                continue  # an option, an optional or repeated positional, or a command list
            text = str(action.help)
            if "default" in text or text.rstrip().endswith("]"):
                claims.append(f"{parser.prog} {action.metavar or action.dest}: {text}")
    assert not claims, claims
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(["report"])
    assert exit_.value.code == 2


@pytest.mark.parametrize("analysis", ["equilibria", "sweep", "phase-portrait"])
def test_an_analysis_input_says_what_it_is_not_only_its_unit(analysis: str) -> None:
    """``analyze equilibria --help`` gave ``--thrust`` the help "N [9.0]" and
    ``--mass-position`` "m [0.0]": a unit, not the quantity (the propeller's thrust, the
    moving mass's position on its rail)."""
    parser = _parser("analyze", analysis)
    quantities = {"--thrust": "thrust", "--roll-torque": "roll torque",
                  "--mass-position": "moving mass", "--current-east": "current"}  # fmt: skip
    for option, quantity in quantities.items():
        assert quantity in _option_help(parser, option), (option, _option_help(parser, option))


@pytest.mark.parametrize(
    ("analysis", "default"),
    [("equilibria", "[horizontal]"), ("phase-portrait", "[horizontal]"),
     ("sweep", "[lateral for roll_torque and mass_position, else horizontal]")],
)  # fmt: skip
def test_each_analysis_gives_the_variant_it_uses_by_default(analysis: str, default: str) -> None:
    """``analyze equilibria --help`` gave ``--variant`` the default "[lateral for
    roll_torque/mass_position sweeps, else horizontal]", the sweep's rule, in a command
    that sweeps nothing."""
    assert _option_help(_parser("analyze", analysis), "--variant").endswith(default)


# the analyses that import scipy.signal and python-control before they refuse (seconds)
SLOW_IMPORT = pytest.mark.slow
# (the command's words, its arguments, an option, a value it refuses, what its help says of
# the values it takes)
RANGES = [
    (("run",), ["bs-3"], "--tolerance", "2", "> 0 and < 1"),
    (("run",), ["bs-3"], "--checkpoint-every", "0", "> 0"),
    (("run",), ["bs-3"], "--real-time", "0", "FACTOR > 0"),
    (("sweep",), ["study.toml"], "--workers", "0", ">= 1"),
    (("sweep",), ["study.toml"], "--max-runs", "0", "1 to 10000000"),
    (("sweep",), ["study.toml"], "--overlay", "21", "1 to 20"),
    pytest.param(
        ("analyze", "sweep"), ["mu", "0", "1"], "--steps", "1", "2 to 100000", marks=SLOW_IMPORT
    ),
    (("analyze", "equilibria"), [], "--thrust", "-1", "> 0"),
    (("analyze", "equilibria"), [], "--mass-position", "1", "the vehicle's stroke"),
    pytest.param(("analyze", "margins"), [], "--step", "0", "> 0", marks=SLOW_IMPORT),
    pytest.param(("analyze", "margins"), [], "--design-speed", "0", "> 0", marks=SLOW_IMPORT),
    pytest.param(("analyze", "margins"), [], "--speed", "0", "> 0", marks=SLOW_IMPORT),
]


@pytest.mark.parametrize(("command", "arguments", "option", "refused", "said"), RANGES)
def test_an_option_s_help_gives_the_values_it_takes(
    command: tuple[str, ...],
    arguments: list[str],
    option: str,
    refused: str,
    said: str,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``run --help`` said of ``--tolerance`` only "the relative error a step may make",
    and a user learnt that it must be below 1 from its refusal; so with
    ``--checkpoint-every``, ``--real-time``, ``--max-runs``, ``--overlay``, ``--steps``
    and the analyses' inputs. Each help states the range, and a value outside it is
    refused in one line naming the option, before anything is built (``--real-time 0``
    was refused after the FMUs' build, half a minute in a new folder)."""
    monkeypatch.chdir(tmp_path)
    shown = _option_help(_parser(*command), option)
    assert said in shown, shown
    assert main([*command, *arguments, option, refused]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{option} " in err, err
    assert not (tmp_path / "build").exists(), err
