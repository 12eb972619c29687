"""``redundik bench``: the resolver benchmark against mink and pink (see ``docs/benchmark.md``).

Heavy imports (Pinocchio, the peers, matplotlib) happen inside the command, so ``redundik --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def bench(
    quick: Annotated[bool, typer.Option("--quick", help="Short run (within a minute).")] = False,
    json_path: Annotated[Path | None, typer.Option("--json", help="Also write the JSON summary here.")] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")] = Path("benchmarks/results"),
    steps: Annotated[
        int | None, typer.Option("--steps", help="Timed steps per case [default 2000, quick 300].")
    ] = None,
    robots: Annotated[
        str | None, typer.Option("--robots", help="Comma-separated: planar3r,panda,panda_tight,talos.")
    ] = None,
    methods: Annotated[
        str | None, typer.Option("--methods", help="Comma-separated: pinv,feedback,wqp,hqp,mink,pink.")
    ] = None,
) -> None:
    """Time pinv, feedback, wqp and hqp (every backend) against mink and pink on identical robots and tasks."""
    from rich.console import Console

    from redundik.peers.bench import BenchConfig, ratio_lines, run_benchmark, write_all

    console = Console()
    config = BenchConfig.quick() if quick else BenchConfig()
    if steps is not None:
        config.steps = steps
    if robots:
        config.robots = tuple(r.strip() for r in robots.split(",") if r.strip())
    if methods:
        config.methods = tuple(m.strip() for m in methods.split(",") if m.strip())
    parts = ["redundik bench"] + (["--quick"] if quick else []) + ([f"--steps {steps}"] if steps else [])
    result = run_benchmark(config, log=lambda msg: console.print(msg, highlight=False))
    paths = write_all(result, out, " ".join(parts), json_path)
    console.print("\nmedian step time / faster peer's (mink or pink, fastest backend):")
    for line in ratio_lines(result):
        console.print("  " + line, highlight=False)
    for t in result.targets():
        mark = {True: "[green]met[/green]", False: "[red]missed[/red]", None: "not measured"}[t["met"]]
        val = "–" if t["value"] is None else f"{t['value']:.3g}"
        console.print(f"  {t['target']}: {val} ({mark})", highlight=False)
    for key, p in paths.items():
        if p is not None:
            console.print(f"{key}: {p}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add the ``bench`` command to the CLI."""
    app.command("bench")(bench)
