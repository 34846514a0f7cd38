"""What the tests share: the repository's paths, the real data (``SLAMESH_DATA``) and the
command to compare with."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

import slamesh

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"


def data_folder() -> Path:
    """The folder SLAMESH_DATA names (relative to the repository root); skips without it, as
    the Rust tests do: with it set, a missing file is a failure."""
    value = os.environ.get("SLAMESH_DATA")
    if not value:
        print("skipped: SLAMESH_DATA is not set")
        pytest.skip("SLAMESH_DATA is not set")
    path = Path(value)
    return path if path.is_absolute() else ROOT / path


def run_command(args: list, tmp: Path) -> None:
    """``slamesh ARGS`` as a separate program: the binary ``SLAMESH_BIN`` names (CI gives the
    one its tests built), else ``slamesh`` on the PATH, else the command inside this module (the
    same code, in this process)."""
    exe = os.environ.get("SLAMESH_BIN") or shutil.which("slamesh")
    args = [str(a) for a in args]
    if exe:
        subprocess.run([exe, *args, "-q"], check=True, cwd=tmp, stdout=subprocess.DEVNULL)
    else:
        slamesh.command(*args, "-q")


@pytest.fixture
def command():
    return run_command
