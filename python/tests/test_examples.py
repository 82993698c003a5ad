"""The README's Python example is python/examples/quickstart.py, it runs, and it prints what
the README's Rust example (examples/quickstart) prints."""

import os
import re
import subprocess
import sys

import pytest

from conftest import REPO

QUICKSTART = REPO / "python/examples/quickstart.py"


def code_of(text):
    """The code after a module docstring."""
    return re.sub(r'^""".*?"""\s*', "", text, flags=re.S).strip()


def test_the_readme_example_is_the_quickstart():
    readme = (REPO / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    assert blocks, "README has no Python example"
    assert blocks[0].strip() == code_of(QUICKSTART.read_text())
    assert len(blocks[0].strip().splitlines()) <= 15


def test_the_quickstart_runs_and_finds_the_press():
    out = subprocess.run([sys.executable, str(QUICKSTART)], cwd=REPO, check=True,
                         capture_output=True, text=True).stdout.splitlines()
    assert len(out) == 7
    contacts = [int(re.search(r"(\d+) contact points", line).group(1)) for line in out]
    assert contacts[0] == 0 and max(contacts) > 0


def test_the_rust_and_python_examples_print_the_same_contacts():
    given = os.environ.get("MOE_TOUCH_QUICKSTART_BIN")
    candidates = [given] if given else [REPO / "target/debug/moe-touch-quickstart",
                                        REPO / "target/release/moe-touch-quickstart"]
    rust = next((c for c in map(str, candidates) if os.path.isfile(c)), None)
    if rust is None:
        if given or os.environ.get("CI"):
            pytest.fail(f"the Rust example is not at {candidates}")
        pytest.skip("no build of the Rust example (cargo build -p moe-touch-quickstart)")
    run = lambda cmd: subprocess.run(cmd, cwd=REPO, check=True, capture_output=True,
                                     text=True).stdout
    python_lines = run([sys.executable, str(QUICKSTART)]).splitlines()
    rust_lines = run([rust]).splitlines()
    assert rust_lines == python_lines


def test_the_soak_runs_two_pipelines_in_two_threads_and_no_frame_fails(monkeypatch):
    """The short form of python/examples/soak.py (run by hand with 20,000 frames)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("soak", REPO / "python/examples/soak.py")
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    monkeypatch.chdir(REPO)
    monkeypatch.setattr(soak, "GAP_EVERY", 15)
    monkeypatch.setattr(soak, "RESET_EVERY", 31)
    monkeypatch.setattr(soak, "REFUSE_EVERY", 23)
    summary = soak.main(frames=50, window=25)
    assert summary["failed"] == 0
    # Frames 23 and 46 of each thread are refused, and only they.
    assert summary["refused"] == 4
    assert summary["frames_per_thread"] == 50 and len(summary["p99_drift"]) == 2
