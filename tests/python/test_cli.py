import subprocess
import sys


def test_demo_prints_a_table():
    out = subprocess.run([sys.executable, "-m", "qogi", "demo"], capture_output=True,
                         text=True, check=True).stdout
    assert "W/(m2 sr)" in out
    assert "288.70" in out


def test_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "qogi", "--help"], capture_output=True,
                         text=True, check=True).stdout
    assert "demo" in out
