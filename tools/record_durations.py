"""Record each test's measured duration for `make test-fast` (tests/durations.json).

Reads the report of a whole-suite run with pytest's ``--durations=0``, sums each test's setup, call
and teardown (a module fixture's cost falls on the test that first asks for it), and writes
{node id: seconds} sorted by node id.  tests/conftest.py marks every test above SLOW_S there as
``slow``, which `make test-fast` leaves out.  Rerun after adding slow tests:

    .venv/bin/python -m pytest -q tests --durations=0 > /tmp/suite.log
    .venv/bin/python tools/record_durations.py /tmp/suite.log

and, where `make test-fast` takes over 3 minutes (a fixture's cost moved to a test left in it),
`make test-fast PYTEST_ADDOPTS=--durations=0 > /tmp/fast.log` and ``--merge /tmp/fast.log``.
"""
from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

LINE = re.compile(r"^\s*([0-9.]+)s\s+(setup|call|teardown)\s+(\S.*?)\s*$")


def parse(text: str) -> dict[str, float]:
    total: dict[str, float] = defaultdict(float)
    for line in text.splitlines():
        m = LINE.match(line)
        if m:
            total[m.group(3)] += float(m.group(1))
    return dict(total)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", help="the output of pytest --durations=0 over the whole suite")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "tests" / "durations.json"))
    ap.add_argument("--merge", action="store_true",
                    help="keep the record's other tests and each test's larger time (a report of part of the suite: "
                         "in `make test-fast` a module fixture's cost falls on another test than in the whole suite)")
    args = ap.parse_args(argv)
    durations = parse(Path(args.report).read_text())
    if not durations:
        raise SystemExit(f"{args.report}: no duration lines (run pytest with --durations=0)")
    if args.merge and Path(args.out).is_file():
        old = json.loads(Path(args.out).read_text())
        durations = {k: max(old.get(k, 0.0), durations.get(k, 0.0)) for k in {*old, *durations}}
    Path(args.out).write_text(json.dumps({k: round(v, 2) for k, v in sorted(durations.items())}, indent=0) + "\n")
    print(f"{len(durations)} tests, {sum(durations.values()):.0f} s in all -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
