"""The book's Python parts cannot rot: its API page is what the package's docstrings say, and the
tutorial's Python script runs."""

import os
import pathlib
import subprocess
import sys

from conftest import ROOT

BOOK = ROOT / "book" / "src"


def test_the_api_page_is_the_packages_docstrings():
    # scripts/python-api-doc renders the installed package's docstrings and signatures.
    page = BOOK / "reference" / "python.md"
    now = subprocess.run([sys.executable, str(ROOT / "scripts" / "python-api-doc")],
                         check=True, capture_output=True, text=True).stdout
    if os.environ.get("JOINTPLAY_BLESS"):
        page.write_text(now)
    assert page.read_text() == now, (
        f"{page} differs from the package's docstrings: regenerate it with "
        "scripts/python-api-doc > book/src/reference/python.md")


def test_the_tutorials_python_chapter_runs(tmp_path):
    script = BOOK / "tutorial" / "four_bar.py"
    done = subprocess.run([sys.executable, str(script), str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    # It writes what its chapter says it writes.
    assert any(pathlib.Path(tmp_path).rglob("*.h5")), sorted(os.listdir(tmp_path))


def test_every_python_file_of_the_book_compiles():
    files = sorted(BOOK.rglob("*.py"))
    assert files
    for f in files:
        compile(f.read_text(), str(f), "exec")


def test_the_python_how_to_runs(tmp_path):
    # book/src/how-to/data.md, "Use it": a scene edited, run and written; a sweep; files loaded.
    script = BOOK / "how-to" / "with_jointplay.py"
    done = subprocess.run([sys.executable, str(script), str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "4ups-rpu-mixed.h5").exists(), sorted(os.listdir(tmp_path))
