"""`vtrack --help` and every command's `--help` print and exit 0 (a help text with a literal
'%' once broke the top-level listing)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from vtrack.cli import _command_modules

NAMES = [mod.NAME for mod in _command_modules()]


def _help(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vtrack", *args, "--help"],
                          capture_output=True, text=True, timeout=120)


def test_top_level_help_lists_every_command():
    res = _help()
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    for name in NAMES:
        assert name in res.stdout
    assert "95% band" in res.stdout            # shown once, not doubled


@pytest.mark.parametrize("name", NAMES)
def test_command_help(name):
    res = _help(name)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("usage: vtrack " + name)
