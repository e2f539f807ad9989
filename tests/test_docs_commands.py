"""Every command docs/*.md shows works as written, as far as it can be told without its work (issue 50).

The commands are found as the reader finds them: inline code (`...`, which may wrap over a line) and
lines indented four spaces or held in a fenced block, that begin with ``jointfem``, ``make``,
``python``, ``.venv/bin/python``, ``.venv/bin/jointfem`` or ``mpirun``, after any environment
assignments (``OPENBLAS_NUM_THREADS=1 ...``).  README.md's are run by tests/test_readme_commands.py.

Most are benchmarks of minutes to hours, so each is checked up to the point where its work begins
(tests/docs_command_run.py), in a folder of its own that links the checkout's demos/, benchmarks/,
tools/, meshes/ and .venv/ (outputs such as ``--out docs/...`` land in it, not in the checkout):

- ``make X``: the target exists (``make -n X`` in the checkout exits 0 and runs nothing).
- ``python SCRIPT ARGS``: the script exists and its argument parser accepts ARGS as written (with
  the environment assignments and under ``mpirun`` where the doc says so); a script that ends or
  writes its outputs without reaching a parser fails.
- ``jointfem CMD ARGS`` with a scene: the real command runs until its sweep would start: the parser,
  the scene, every ``--set``, the reduction's options, the output folder, the model and its checks
  of memory, time and forcing all passed (under 1.5 s each).  None is run to its end here: each is
  a sweep of the jointed beam, at its own H = 5 the one tests/test_readme_commands.py runs with
  ``--out`` (40 s in tests/durations.json), at H = 15 with the event law 330 s (720 points, beside
  another job), at H = 41 with the exact condensation minutes (docs/benchmarks_harmonics.md).
- ``jointfem CMD --option ...`` with no scene names a command or its options in prose: the command
  and each option exist, and each option's value is one it takes.

Bare ``python`` and ``jointfem`` are the set-up's (.venv/bin, first on PATH as an activated .venv
puts them).  A placeholder folder (``--out DIR``) is taken as written: any name is a folder name to
the parser, and the check stops before it is read or written.
"""
from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys

import pytest

from conftest import ROOT
from docs_command_run import NOT_REACHED, PARSED, READY, WROTE

RUNNER = ROOT / "tests" / "docs_command_run.py"
VENV = ROOT / ".venv" / "bin"
START = re.compile(r"(?:[A-Z][A-Z0-9_]*=\S*\s+)*(?:jointfem|make|python|\.venv/bin/python|\.venv/bin/jointfem|mpirun)"
                   r"(?=\s|$)")
LINKS = ("demos", "benchmarks", "tools", "meshes", ".venv")

# Shown in the docs, not commands, so neither run nor checked as commands; each why:
EXCLUDED = {
    # usage lines: SCENE, K, M, DIR are the reader's values and [...] the optional parts (the
    # command and each option named are still checked: test_every_synopsis_names_what_jointfem_has;
    # tests/test_nma.py runs `jointfem nma` with --frf and --out)
    "jointfem nma SCENE [--mode K] [--method M] [--frf DIR] --out DIR": "synopsis",
    "jointfem nma SCENE": "synopsis: the command and what it takes",
    # the launcher named in prose about the distributed stage, no program after it
    # (tests/test_distributed.py runs that stage under `mpirun -n 2`)
    "mpirun -n 2": "the launcher, no program",
    "mpirun": "the launcher, no program",
}

# Placeholders the parser would refuse or that stand for several values, each replaced by the
# concrete commands it stands for; each why:
CONCRETE = {
    # the sentence reproduces the table above it, H = 5 to 15 (the sampled full model's range)
    "jointfem frf demos/beam2d.toml --harmonics H": [
        "jointfem frf demos/beam2d.toml --harmonics 5", "jointfem frf demos/beam2d.toml --harmonics 15"],
    # the line before it (`cp tools/record_points.py /tmp/before/tools/`) puts this same script in a
    # worktree of the older commit; the test has no such worktree
    ".venv/bin/python /tmp/before/tools/record_points.py /tmp/before.npz": [
        ".venv/bin/python tools/record_points.py /tmp/before.npz"],
}


def _blank(text: str, start: int, end: int) -> str:
    """The text with [start, end) turned to spaces (newlines kept): found once, not twice."""
    return text[:start] + re.sub(r"[^\n]", " ", text[start:end]) + text[end:]


def _found(text: str) -> list[str]:
    """The commands of one document in their order, whitespace as rendered, comments dropped."""
    hits = []
    for m in re.finditer(r"^```[^\n]*\n(.*?)^```", text, re.S | re.M):
        for line in re.finditer(r"^[ \t]*(\S.*)$", m.group(1), re.M):
            if START.match(line.group(1)):
                hits.append((m.start(1) + line.start(1), line.group(1)))
        text = _blank(text, m.start(), m.end())
    for m in re.finditer(r"^ {4,}(\S.*)$", text, re.M):
        if START.match(m.group(1)):
            hits.append((m.start(1), m.group(1)))
            text = _blank(text, m.start(), m.end())
    for m in re.finditer(r"(?<!`)`([^`]+)`(?!`)", text):
        words = " ".join(m.group(1).split())
        if START.match(words):
            hits.append((m.start(1), words))
    return [shlex.join(shlex.split(c, comments=True)) if "#" in c else c for _, c in sorted(hits)]


FOUND = [(f"{doc.name}#{n}", command) for doc in sorted((ROOT / "docs").glob("*.md"))
         for n, command in enumerate(_found(doc.read_text()))]
CHECKED = [(where, command) for where, command in FOUND if command not in EXCLUDED]


def test_the_docs_show_commands():
    """The search finds the kinds of command the docs show (a regex that found nothing would pass
    every test below)."""
    kinds = {shlex.split(c)[0] for _, c in FOUND}
    assert {"make", "python", ".venv/bin/python", "jointfem", "mpirun"} <= kinds, kinds
    assert any(c.startswith("OPENBLAS_NUM_THREADS=1 ") for _, c in FOUND)
    assert any(c.startswith("mpirun -n 2 python ") for _, c in FOUND)  # wrapped over two lines in theory.md
    assert len(CHECKED) >= 60, len(CHECKED)


def test_every_exception_is_in_the_docs():
    """An exclusion or a placeholder rule no doc shows any more is dropped, not kept for nothing."""
    shown = {c for _, c in FOUND}
    assert set(EXCLUDED) <= shown, set(EXCLUDED) - shown
    assert set(CONCRETE) <= shown, set(CONCRETE) - shown


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg", PATH=f"{VENV}{os.pathsep}{os.environ['PATH']}")


def _run(words: list[str], where, env: dict, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run in a session of its own, so that a timeout ends mpirun's ranks too."""
    with subprocess.Popen(words, cwd=where, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          start_new_session=True) as p:
        try:
            out, err = p.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            out, err = p.communicate()
            err += f"\n(killed after {timeout} s: it reached neither its parser nor its sweep)"
        return subprocess.CompletedProcess(words, p.returncode, out, err)


def _interpreter(word: str, where) -> str:
    return str(VENV / "python") if word == "python" else str(where / word)


def _program(words: list[str], where) -> tuple[list[str], int]:
    """A documented ``python SCRIPT ARGS`` or ``jointfem ARGS`` as the runner's command, and the exit
    code that says it stopped where its work begins."""
    if words[0] in ("python", ".venv/bin/python"):
        script = words[1]
        assert not script.startswith("-"), f"{words}: only SCRIPT ARGS is checked"
        assert (where / script).is_file(), f"{script}: no such script"
        return [_interpreter(words[0], where), str(RUNNER), "parse", *words[1:]], PARSED
    if words[0] in ("jointfem", ".venv/bin/jointfem"):
        # the runner stops these at their continuation; another command would do its work here
        assert words[1] in ("frf", "nma", "force"), f"{words}: tests/docs_command_run.py cannot stop it"
        entry = VENV / "jointfem" if words[0] == "jointfem" else where / words[0]
        return [str(VENV / "python"), str(RUNNER), "sweep", str(entry), *words[1:]], READY
    raise AssertionError(f"{words}: not a program this test knows")


def _names(words: list[str]) -> None:
    """``jointfem CMD --option [value] ...`` in prose: CMD and each option exist, and a value is one
    of the option's choices where it has them."""
    from jointfem.cli import build_parser

    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    assert words[1] in commands, f"jointfem has no command {words[1]!r} (it has {', '.join(commands)})"
    options = commands[words[1]]._option_string_actions
    for k, word in enumerate(words[2:], 2):
        if word.startswith("-"):
            assert word in options, f"jointfem {words[1]} has no option {word}"
            choices = options[word].choices
            value = words[k + 1] if k + 1 < len(words) else "-"
            if choices is not None and not value.startswith("-") and not value.isupper():  # (K, DIR: a synopsis's)
                assert value in choices, f"jointfem {words[1]} {word}: {value!r} is not one of {choices}"


def _check(command: str, where) -> None:
    words = shlex.split(command)
    env = _env()
    while re.fullmatch(r"[A-Z][A-Z0-9_]*=.*", words[0]):  # as the shell: for this command only
        name, value = words.pop(0).split("=", 1)
        env[name] = value
    if words[0] == "make":
        r = _run(["make", "-n", *words[1:]], ROOT, env, timeout=60)
        assert r.returncode == 0, (command, r.stderr[-2000:])
        return
    if words[0] in ("jointfem", ".venv/bin/jointfem") and (len(words) < 3 or words[2].startswith("-")):
        _names(words)
        return
    launcher = []
    if words[0] == "mpirun":
        k = 1
        while words[k].startswith("-"):  # mpirun's own options and their values (-n 2)
            k += 2 if words[k] in ("-n", "-np") else 1
        # as root mpirun takes --allow-run-as-root, and the machine may have fewer cores than ranks
        launcher = ["mpirun", *(["--allow-run-as-root"] if os.geteuid() == 0 else []), "--oversubscribe", *words[1:k]]
        words = words[k:]
    program, stopped = _program(words, where)
    r = _run(launcher + program, where, env)
    assert r.returncode == stopped, (command, r.returncode, r.stderr[-2000:])


@pytest.mark.parametrize("synopsis", [c for c in EXCLUDED if c.startswith("jointfem ")])
def test_every_synopsis_names_what_jointfem_has(synopsis):
    _names(synopsis.replace("[", " ").replace("]", " ").split())


@pytest.mark.parametrize("where,command", CHECKED, ids=[w for w, _ in CHECKED])
def test_every_docs_command_works_as_written(where, command, tmp_path):
    for name in LINKS:
        (tmp_path / name).symlink_to(ROOT / name)
    (tmp_path / "docs").mkdir()
    for concrete in CONCRETE.get(command, [command]):
        _check(concrete, tmp_path)



SCRIPTS = {  # what the runner is to tell of each: (exit code, script)
    "parses.py": (PARSED, "import argparse\nargparse.ArgumentParser().parse_args()\nraise SystemExit('worked')\n"),
    "refuses.py": (2, "import argparse\nargparse.ArgumentParser().parse_args(['--x'])\n"),
    "no_parser.py": (NOT_REACHED, "print('ends')\n"),
    "writes_first.py": (WROTE, "open('out.txt', 'w')\nimport argparse\nargparse.ArgumentParser().parse_args()\n"),
}


@pytest.mark.parametrize("name", SCRIPTS)
def test_the_runner_tells_where_a_script_stopped(name, tmp_path):
    """What the checks above rely on: a script is stopped right after its parser accepted the
    arguments, before its work; argparse's refusal comes through; a script that ends without a
    parser is not taken for one that parses; one that writes its outputs before any parser is
    stopped before the file is made."""
    code, text = SCRIPTS[name]
    (tmp_path / name).write_text(text)
    r = _run([sys.executable, str(RUNNER), "parse", name], tmp_path, _env(), timeout=60)
    assert r.returncode == code, (r.returncode, r.stderr)
    assert "worked" not in r.stderr and not (tmp_path / "out.txt").exists()
