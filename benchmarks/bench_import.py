"""Start-up cost: ``python -m scart --help``, ``import scart``, ``scart validate`` of the
calculator, against a bare ``python -c pass`` measured in the same run.

Run: ``python benchmarks/bench_import.py [--quick | --smoke] [--tree PATH] [--runs N]``
(prints a table; no assertions; ``--quick``: 5 runs, ``--smoke``: 1, that it runs). ``--tree`` points at another checkout (for example an older commit made with
``git worktree add``) to compare before and after with the same interpreter: its folder
goes first on ``PYTHONPATH``. Each figure is the median wall time of ``--runs`` fresh
processes, and the number of modules the command leaves in ``sys.modules``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

PROBE = "import sys, runpy; sys.argv = {argv!r}; {body}; print(len(sys.modules), file=sys.stderr)"


def measure(tree: Path, code: str, runs: int) -> tuple[float, int]:
    """Median wall time (s) of ``python -c code`` and the modules it loaded."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    times, modules = [], 0
    for _ in range(runs):
        start = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                             cwd=tree)
        times.append(time.perf_counter() - start)
        lines = out.stderr.strip().splitlines()
        modules = int(lines[-1]) if lines and lines[-1].isdigit() else -1
    return statistics.median(times), modules


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, default=ROOT, help="checkout to measure (default: this one)")
    parser.add_argument("--runs", type=int, default=None, help="fresh processes per command (default 15)")
    parser.add_argument("--quick", action="store_true", help="5 runs each")
    parser.add_argument("--smoke", action="store_true", help="1 run each: that it runs")
    args = parser.parse_args()
    args.runs = args.runs or (1 if args.smoke else 5 if args.quick else 15)
    tree = args.tree.resolve()
    calc = str(tree / "composites" / "calculator" / "calculator.composite")
    cases = {
        "python -c pass (baseline)": "import sys; print(len(sys.modules), file=sys.stderr)",
        "import scart": "import sys, scart; print(len(sys.modules), file=sys.stderr)",
        "scart --help": PROBE.format(argv=["scart", "--help"],
                                     body="import contextlib, io\nwith contextlib.redirect_stdout(io.StringIO()):\n"
                                          "    try: runpy.run_module('scart', run_name='__main__')\n"
                                          "    except SystemExit: pass"),
        "scart validate calculator": PROBE.format(argv=["scart", "validate", calc],
                                                  body="import contextlib, io\n"
                                                       "with contextlib.redirect_stdout(io.StringIO()):\n"
                                                       "    try: runpy.run_module('scart', run_name='__main__')\n"
                                                       "    except SystemExit: pass"),
    }
    print(f"tree: {tree}  ({args.runs} runs each, median)")
    print(f"{'command':<30} {'time':>9} {'ratio':>7} {'modules':>8}")
    base = None
    for name, code in cases.items():
        t, mods = measure(tree, code, args.runs)
        base = base or t
        print(f"{name:<30} {t * 1000:7.0f} ms {t / base:6.1f}x {mods:8d}")


if __name__ == "__main__":
    main()
