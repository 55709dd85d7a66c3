"""cli/__init__.py: the parser lists every command and builds without torch; bad arguments and input errors of
every command end in one line on stderr with exit code 2."""

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import cli
from core.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
NAMES = [importlib.import_module(f"cli.{module}").NAME for module in cli.COMMANDS]


def test_help_runs_and_the_parser_imports_no_torch():
    """The one subprocess test: ``python infer.py --help`` works, and building the parser imports no torch."""
    proc = subprocess.run([sys.executable, "infer.py", "--help"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stderr == ""
    assert all(name in proc.stdout for name in NAMES)
    proc = subprocess.run([sys.executable, "-c", "import sys, cli; cli.build_parser(); print('torch' in sys.modules)"],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.strip() == "False", proc.stderr


@pytest.mark.parametrize("name", NAMES)
def test_every_command_has_help(name, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main([name, "--help"])
    assert exit_.value.code == 0 and capsys.readouterr().out.startswith(f"usage: infer.py {name}")


@pytest.mark.parametrize("name", NAMES)
def test_every_command_rejects_bad_arguments_in_one_line(name, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main([name, "--no-such-option"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and len(err.splitlines()) == 1, err
    assert err.startswith(f"infer.py {name}: error: ") or err.startswith("infer.py: error: "), err
    assert "--no-such-option" in err or "required" in err, err


@pytest.mark.parametrize(("argv", "message"), [([], "required: COMMAND"), (["nope"], "invalid choice: 'nope'")])
def test_missing_or_unknown_command(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and len(err.splitlines()) == 1 and message in err, err


@pytest.mark.parametrize("error", [InputError("bad.tif is not a DEM"), FileNotFoundError("bad.tif is not a DEM")])
def test_input_errors_of_a_command_end_in_one_line(error, monkeypatch, capsys):
    def run(args):
        raise error

    monkeypatch.setattr("cli.demo.run", run)  # bound when the parser is built
    assert cli.main(["demo"]) == 2
    assert capsys.readouterr().err == "infer.py demo: error: bad.tif is not a DEM\n"


def test_other_errors_are_not_hidden(monkeypatch):
    def run(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr("cli.demo.run", run)
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main(["demo"])
