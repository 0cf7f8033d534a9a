"""The type checker over the package: mypy (pinned in requirements-dev.txt, setup.cfg)."""
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parent.parent


def test_mypy_finds_no_error_in_the_package():
    result = subprocess.run([sys.executable, '-m', 'mypy', 'ams_can_bridge'], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
