"""The book for people who installed the package: a wheel, installed outside the repository.

Builds lagolib's wheel, installs it into a fresh virtual environment (its dependencies come from
the environment running the tests: ``--system-site-packages``, so no download but the build
backend), and, from a folder outside the repository, checks that the installed lagolib is the
wheel's, that it holds the book, and that ``lagolib book write`` and ``lagolib book
student-copies`` write the full book and the student copies; then runs the written preface.
"""

import json
import os
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from lagolib import book as lbook

ROOT = Path(__file__).resolve().parent.parent
BOOK = ROOT / "book"


def _run(args, cwd, env=None, timeout=600):
    proc = subprocess.run(args, cwd=cwd, capture_output=True, text=True, env=env, timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, args))}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(ROOT)], out)
    (path,) = out.glob("lagolib-*.whl")
    return path


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory):
    """``(python, lagolib command, environment, a working folder outside the repository)``."""
    home = tmp_path_factory.mktemp("installed")
    env_dir = home / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=True).create(env_dir)
    bindir = env_dir / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / "python"
    _run([python, "-m", "pip", "install", "--no-deps", "-q", str(wheel)], home)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{bindir}{os.pathsep}{env['PATH']}"
    work = home / "work"
    work.mkdir()
    return python, bindir / "lagolib", env, work


def test_the_wheel_holds_the_book_and_names_the_project(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for p in BOOK.glob("*.ipynb"):
        assert f"lagolib/_book/{p.name}" in names, p.name
    for name in ("_toc.yml", "_config.yml", "_static/lagolib.css", "equation_index.md"):
        assert f"lagolib/_book/{name}" in names
    assert "lagolib/_data/manhattan200.g2o" in names  # the offline stand-ins the chapters use
    assert not [n for n in names if "/_build/" in n or n.endswith("conftest.py")]
    meta = next(n for n in names if n.endswith("METADATA"))
    text = zipfile.ZipFile(wheel).read(meta).decode()
    assert "Project-URL: Homepage, https://" in text
    assert "Project-URL: Documentation, https://" in text


def test_an_installed_lagolib_writes_the_book_and_the_student_copies(installed):
    python, lagolib_cmd, env, work = installed
    where = _run(
        [
            python,
            "-c",
            "import lagolib, lagolib.book as b; print(lagolib.__file__); print(b.book_dir())",
        ],
        work,
        env,
    )
    module, book = where.split()
    assert ROOT not in Path(module).parents, f"the repository's lagolib was imported: {module}"
    assert Path(book).parts[-2:] == ("lagolib", "_book")
    out = _run([lagolib_cmd, "book", "write", "mybook"], work, env)
    n = len(list(BOOK.glob("*.ipynb")))
    assert out.startswith(f"wrote the book: {n} chapters with ")
    assert "next: jupyter lab mybook/00_preface.ipynb" in out
    for p in BOOK.glob("*.ipynb"):
        assert (work / "mybook" / p.name).read_bytes() == p.read_bytes(), p.name
    out = _run([lagolib_cmd, "book", "student-copies", "class", "--no-hints"], work, env)
    assert out.startswith(f"wrote student copies of {n} chapters with ")
    copy = json.loads((work / "class" / "06_lago.ipynb").read_text(encoding="utf-8"))
    assert copy["metadata"]["lagolib"]["student_copy"] is True
    assert copy["metadata"]["lagolib"]["hints"] is False
    assert not any("solution" in c["metadata"].get("tags", []) for c in copy["cells"])
    assert lbook.exercises(copy) == lbook.exercises(
        lbook.student_copy(
            json.loads((BOOK / "06_lago.ipynb").read_text(encoding="utf-8")), hints=False
        )
    )


@pytest.mark.book
def test_the_written_preface_runs_in_the_installed_lagolib(installed):
    python, lagolib_cmd, env, work = installed
    _run([lagolib_cmd, "book", "write", "runbook"], work, env)
    env = dict(
        env,
        LAGOLIB_OFFLINE="1",
        LAGOLIB_CACHE=str(work / "cache"),
        LAGOLIB_BOOK_STRICT="1",
        MPLBACKEND="",
    )
    env.pop("LAGOLIB_DATA", None)
    _run(
        [
            python,
            "-c",
            (
                "import nbformat; from nbclient import NotebookClient; "
                "nb = nbformat.read('00_preface.ipynb', as_version=4); "
                "NotebookClient(nb, timeout=120, kernel_name='python3').execute(); "
                "import lagolib; print(lagolib.__file__)"
            ),
        ],
        work / "runbook",
        env,
    )


def test_the_build_hook_skips_what_lagolib_book_skips():
    import ast

    tree = ast.parse((ROOT / "hatch_build.py").read_text(encoding="utf-8"))
    (value,) = [
        n.value for n in tree.body
        if isinstance(n, ast.Assign) and n.targets[0].id == "NOT_THE_BOOK"
    ]
    assert ast.literal_eval(value) == lbook.NOT_THE_BOOK
