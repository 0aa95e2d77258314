"""Interpreter throughput and bounds: programs whose moves come from loops and subroutines.

    .venv/bin/python benchmarks/bench_interp.py [--moves 1000000] [--repeat 1]

The program: a subroutine that cuts one zig-zag row (a `while` loop of G1 moves whose end points are
expressions of parameters) called from an outer `repeat` loop, so every move is interpreted (expressions
evaluated, control flow taken, modal state updated) and none is a copied line. Prints executed blocks/s
and moves/s per second of the process's CPU time (the figure that does not depend on what else
the machine runs) and per wall second, and the peak RSS. Target (issue 27): >= 200k blocks/s. A second figure, the runaway-loop
limit, checks that `while [1]` stops with its line named after max_blocks blocks.
"""

from __future__ import annotations

import argparse
import resource
import time

from feedlog.errors import ProgramError
from feedlog.toolpath.interp import interpret


def program(moves: int, per_row: int = 1000) -> str:
    rows = max(1, moves // per_row)
    return "\n".join([
        "G21 G90 G17 G94 G64 P0.01 F3000",
        "o<row> sub",
        "  #<i> = 0",
        "  o10 while [#<i> LT #2]",
        "    G1 X[#<i> * 0.05] Y[#1 * 0.5 + [#<i> MOD 2] * 0.1]",
        "    #<i> = [#<i> + 1]",
        "  o10 endwhile",
        "o<row> endsub",
        "#1 = 0",
        f"o20 repeat [{rows}]",
        f"  o<row> call [#1] [{per_row}]",
        "  #1 = [#1 + 1]",
        "o20 endrepeat",
        "M2", ""])


# the same rows in Fanuc macro B and in Sinumerik: nested WHILE loops, end points expressions of variables
_DIALECT_LINES = {
    "fanuc": ["G21 G90 G17 G94 F3000.", "#1 = 0", "WHILE [#1 LT {rows}] DO 1", "#2 = 0", "WHILE [#2 LT {per_row}] DO 2",
              "G1 X[#2 * 0.05] Y[#1 * 0.5 + [#2 MOD 2] * 0.1]", "#2 = #2 + 1", "END 2", "#1 = #1 + 1", "END 1"],
    "sinumerik": ["G71 G90 G17 G94 F3000", "R1 = 0", "WHILE R1 < {rows}", "R2 = 0", "WHILE R2 < {per_row}",
                  "G1 X=R2*0.05 Y=R1*0.5+(R2 MOD 2)*0.1", "R2 = R2 + 1", "ENDWHILE", "R1 = R1 + 1", "ENDWHILE"],
}


def dialect_program(dialect: str, moves: int, per_row: int = 1000) -> str:
    rows = max(1, moves // per_row)
    return "\n".join([line.format(rows=rows, per_row=per_row) for line in _DIALECT_LINES[dialect]] + ["M30", ""])


def run_dialect(dialect: str, moves: int, repeat: int) -> None:
    """Fanuc or Sinumerik front-end throughput on the same motion."""
    if dialect == "fanuc":
        from feedlog.toolpath.interp.fanuc import interpret_fanuc as run
        text, name = dialect_program("fanuc", moves), "bench.nc"
    else:
        from feedlog.toolpath.interp.sinumerik import interpret_sinumerik as run
        text, name = dialect_program("sinumerik", moves), "bench.mpf"
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        prog = run(text, name=name)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        blocks = prog.metadata.get("blocks_executed", 0)
        n = len(prog.motion)
        print(f"{dialect}: {blocks} blocks ({n} moves) in {dt:.2f} s wall, {cpu:.2f} s CPU: {blocks / cpu:,.0f} "
              f"blocks/s and {n / cpu:,.0f} moves/s of CPU time")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--stream", action="store_true",
                    help="read the program batch by batch (InterpretedReader, as `feedlog program --stream` and "
                         "window-by-window simulation do) and keep only counts: the memory bound of streaming")
    ap.add_argument("--dialect", choices=("rs274ngc", "fanuc", "sinumerik"), default="rs274ngc",
                    help="the front-end to measure (fanuc, sinumerik: the same rows in their languages)")
    args = ap.parse_args()
    if args.dialect != "rs274ngc":
        run_dialect(args.dialect, args.moves, args.repeat)
        return
    text = program(args.moves)
    if args.stream:
        from feedlog.toolpath.interp.reader import InterpretedReader
        t0, c0 = time.perf_counter(), time.process_time()
        reader = InterpretedReader(text, name="bench.ngc")
        rows = sum(len(batch) for batch in reader)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        blocks = reader.metadata["blocks_executed"]
        print(f"streamed {blocks} blocks ({rows} rows, {reader.batches} batches) in {dt:.2f} s wall, {cpu:.2f} s "
              f"CPU: {blocks / cpu:,.0f} blocks/s of CPU time; peak RSS "
              f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
        return
    for _ in range(args.repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        prog = interpret(text, name="bench.ngc")
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        blocks = prog.metadata["blocks_executed"]
        moves = len(prog.motion)
        print(f"interpreted {blocks} blocks ({moves} moves) in {dt:.2f} s wall, {cpu:.2f} s CPU: "
              f"{blocks / cpu:,.0f} blocks/s and {moves / cpu:,.0f} moves/s of CPU time "
              f"({blocks / dt:,.0f} blocks/s wall)")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    t0 = time.perf_counter()
    try:
        interpret("o1 while [1]\nG0 X1\no1 endwhile\nM2\n", name="runaway.ngc", max_blocks=200_000)
    except ProgramError as exc:
        print(f"runaway loop stopped after {time.perf_counter() - t0:.2f} s: {exc}")


if __name__ == "__main__":
    main()
