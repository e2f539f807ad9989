"""Run by tests/test_docs_commands.py in place of a documented command's interpreter:

    python tests/docs_command_run.py parse SCRIPT ARGS...   (as `python SCRIPT ARGS...`)
    python tests/docs_command_run.py sweep .venv/bin/jointfem ARGS...   (as `jointfem ARGS...`)

runs SCRIPT as ``python SCRIPT`` would (``__main__``, sys.argv, its folder first on sys.path) and
stops it without doing its work, by exit code:

- parse: right after argparse accepted the arguments (PARSED); argparse's own refusal exits 2;
- sweep: when the command reaches the sweep, backbone or force continuation (READY), that is after
  its arguments, scene, ``--set`` overrides, reduction options, output folder, model and the checks
  of the time and memory it would take were all accepted.

A script that returns or exits without reaching that point exits NOT_REACHED, not 0: it did its
work (or none) without the arguments being checked.  A script that opens a file for writing under
the working folder or the checkout before it (its outputs: the work has begun) exits WROTE, before
the file is made.
"""
import argparse
import os
import runpy
import sys
from pathlib import Path

PARSED, READY, WROTE, NOT_REACHED = 97, 95, 96, 98


def stop(code: int, what: str):
    sys.stdout.flush()
    print(f"docs_command_run: {what}", file=sys.stderr, flush=True)
    os._exit(code)  # no atexit, finally or MPI finalisation: nothing the script would do after this


def guard_writes():
    """Refuse any file opened for writing under the working folder or the checkout (bytecode and
    numba caches, which imports write, apart)."""
    places = [Path.cwd().resolve(), Path(__file__).resolve().parents[1]]
    writing = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC

    def hook(event, args):
        if event != "open" or not isinstance(args[0], (str, bytes, os.PathLike)) or not (args[2] or 0) & writing:
            return
        path = Path(os.fsdecode(args[0])).resolve()
        if "__pycache__" in path.parts:
            return
        if any(path == p or p in path.parents for p in places):
            stop(WROTE, f"opened {path} for writing before its arguments were checked")

    sys.addaudithook(hook)


def stop_after_parsing():
    original = argparse.ArgumentParser.parse_args

    def parse_args(self, args=None, namespace=None):
        original(self, args, namespace)  # argparse's refusal: its message and exit 2, as written
        stop(PARSED, f"{self.prog}: arguments accepted")

    argparse.ArgumentParser.parse_args = parse_args


def stop_at_the_sweep():
    import jointfem.analysis.force as force
    import jointfem.analysis.nma as nma
    import jointfem.app as app

    def reached(*args, **kwargs):
        stop(READY, "reached the sweep with every check passed")

    app.compute_frf = reached  # app.solve_scene calls it by this name
    nma.compute_backbone = reached  # app.solve_nma imports it from here when called
    force.compute_force_response = reached  # as cli.cmd_force


def main():
    mode, script, *args = sys.argv[1:]
    {"parse": stop_after_parsing, "sweep": stop_at_the_sweep}[mode]()
    sys.argv = [script, *args]
    sys.path[0] = str(Path(script).resolve().parent)  # as `python SCRIPT`: its folder, not tests/
    guard_writes()
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exc:
        if exc.code not in (None, 0):
            raise
    stop(NOT_REACHED, f"{script} ended without reaching its {'argument parser' if mode == 'parse' else 'sweep'}")


if __name__ == "__main__":
    main()
