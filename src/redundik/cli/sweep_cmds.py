"""``redundik sweep FILE``: many IK problems from a sweep file, in-process or on Dask (extra ``sweep``).

Self-contained: Pinocchio, pyarrow, matplotlib and Dask are imported inside the command (Dask only when asked for),
so ``redundik --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from redundik.cli._params import path_value


def sweep(
    file: Annotated[
        Path,
        typer.Argument(
            help="Sweep file (YAML), e.g. sweeps/panda_reach.yaml, or the name of a shipped one (panda_reach).",
            show_default=False,
        ),
    ],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", parser=path_value, help="Output folder (default: out/NAME).")
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="Result table format: parquet or csv.")] = "parquet",
    dask: Annotated[
        str | None, typer.Option("--dask", help="Run on a new Dask LocalCluster of N single-threaded workers: local:N.")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Run on an existing Dask cluster (scheduler address).")
    ] = None,
    figure: Annotated[bool, typer.Option("--figure/--no-figure", help="Write the map figure NAME_map.png.")] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only the final line.")] = False,
) -> None:
    """Run every problem of a sweep file; write NAME.parquet (or .csv), NAME_map.png and summary.json."""
    from rich.console import Console

    from redundik.cli.example_cmds import resolve_file
    from redundik.errors import RedundikError
    from redundik.reporting.paths import check_output_folder
    from redundik.sweep import load_sweep, run_sweep
    from redundik.sweep.engine import check_scheduler_address, parse_local
    from redundik.sweep.output import FORMATS, write_outputs

    if fmt not in FORMATS:
        raise RedundikError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt[:40]!r}")
    if dask is not None and scheduler is not None:
        raise RedundikError("give at most one of --dask local:N and --scheduler ADDRESS")
    if dask is not None:
        parse_local(dask)  # refused before the file is loaded
    if scheduler is not None:
        check_scheduler_address(scheduler)
    console = Console(stderr=True)
    plan = load_sweep(resolve_file(file, "sweeps"))  # a path, or the name of a shipped sweep file
    out_dir = check_output_folder(out if out is not None else Path("out") / plan.name)  # refused before the work
    where = f"dask {dask}" if dask else f"dask {scheduler}" if scheduler else "in-process"
    if not quiet:
        console.print(
            f"{plan.name}: {plan.n_problems} problems ({plan.n_targets} targets × {plan.n_starts} starts), "
            f"{plan.spec.resolver.name}, chunks of {plan.spec.chunk_size}, {where}",
            highlight=False,
        )

    def progress(done: int, total: int) -> None:
        if not quiet and (done == total or done % max(total // 10, 1) == 0):
            console.print(f"  {done}/{total} chunks", highlight=False)

    result = run_sweep(plan, dask=dask, scheduler=scheduler, progress=progress)
    paths = write_outputs(plan, result, out_dir, fmt, figure)
    pct = 100.0 * result.n_converged / max(result.n_problems, 1)
    typer.echo(
        f"{plan.name}: {result.n_converged}/{result.n_problems} converged ({pct:.1f} %) in {result.seconds:.1f} s "
        f"on {result.engine}; wrote {', '.join(str(p) for p in paths.values())}"
    )


def register(app: typer.Typer) -> None:
    """Add the ``sweep`` command to the CLI."""
    app.command("sweep")(sweep)
