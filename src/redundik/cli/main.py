"""Entry point of the ``redundik`` command.

Each command group lives in its own module and registers itself on the app through a ``register`` function, so
this file only lists them. Errors derived from :class:`~redundik.errors.RedundikError` are printed as one line on
stderr (and, under ``--json``, as one JSON document on stdout), never as a traceback; the exit code says which
kind of failure it was (:data:`EXIT_CODES`). Nothing numerical is imported here: ``redundik --help`` and
``redundik validate BAD.yaml`` start in a fraction of a second.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import Any

from redundik._extras import is_installed, missing
from redundik._version import __version__
from redundik.errors import ConfigError, MissingDependencyError, RedundikError, ResolverError, SimulationError

#: Exit codes of the ``redundik`` command.
EXIT_OK, EXIT_ABORTED, EXIT_USAGE, EXIT_INVALID, EXIT_FAILED, EXIT_MISSING = 0, 1, 2, 3, 4, 5
#: What typer's non-standalone mode returns for a Ctrl-C inside a command (its ``Exit(130)``).
TYPER_INTERRUPTED = 130
#: An unexpected exception (a bug): 70, EX_SOFTWARE of sysexits.h.
EXIT_INTERNAL = 70
EXIT_CODES = {
    EXIT_OK: "success",
    EXIT_ABORTED: "aborted (Ctrl-C)",
    EXIT_USAGE: "usage error: unknown command or option, missing argument, a value of the wrong type",
    EXIT_INVALID: "invalid input: a file or value refused, one line 'error: KEY.PATH: what was expected'",
    EXIT_FAILED: "run failure: a valid run could not finish (diverged, a QP solver failed)",
    EXIT_MISSING: "an optional dependency is missing: the message names the extra to install",
    EXIT_INTERNAL: "internal error: a bug in redundik, one line naming the exception (REDUNDIK_TRACEBACK=1 shows it)",
}
#: The help's epilog: one exit code a line (``\b``: click does not re-wrap the paragraph, a code never ends a line).
EPILOG = "\b\nExit codes:\n" + "\n".join(f"  {k} {v}" for k, v in EXIT_CODES.items())

_APP: Any = None


def exit_code(exc: RedundikError) -> int:
    """The exit code of an error: :data:`EXIT_FAILED` for failures of a running job, else :data:`EXIT_INVALID`."""
    from redundik._optional import ExtraImportError  # standard library and redundik.errors only

    if isinstance(exc, (MissingDependencyError, ExtraImportError)):
        return EXIT_MISSING
    if isinstance(exc, (SimulationError, ResolverError)):  # SolverError is a ResolverError
        return EXIT_FAILED
    return EXIT_INVALID


def _app() -> Any:
    """The typer app, built once (main() is called many times in one process by the tests)."""
    global _APP
    if _APP is not None:
        return _APP
    for module in ("typer", "rich"):
        if not is_installed(module):
            raise missing(module, "the redundik command")
    import typer

    app = typer.Typer(
        name="redundik",
        help="Differential inverse kinematics of redundant robots.",
        epilog=EPILOG,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode=None,  # help text is plain: units in brackets ("[deg]") are shown, not eaten as markup
    )

    def version(value: bool) -> None:
        if value:
            typer.echo(f"redundik {__version__}")
            raise typer.Exit()

    @app.callback()
    def _root(
        show_version: bool = typer.Option(
            False, "--version", callback=version, is_eager=True, help="Print the version and exit."
        ),
    ) -> None:
        """Differential inverse kinematics of redundant robots."""

    from redundik.cli import bench_cmds, example_cmds, parallel_cmds, run_cmds, view_cmds

    run_cmds.register(app)
    example_cmds.register(app)
    parallel_cmds.register(app)
    bench_cmds.register(app)
    view_cmds.register(app)
    __import__("redundik.cli.sweep_cmds", fromlist=["register"]).register(app)  # issue 11: redundik sweep
    _APP = app
    return app


def _aborted() -> int:
    """Ctrl-C: one line (and the JSON record with ``--json``); what was written so far may be incomplete."""
    from redundik.cli._console import JSON_MODE, emit_json

    text = "aborted (Ctrl-C): what was written so far may be incomplete"
    if JSON_MODE["on"]:
        emit_json({"ok": False, "error": text, "exit_code": EXIT_ABORTED, "kind": "KeyboardInterrupt"})
    print(text, file=sys.stderr)
    return EXIT_ABORTED


def _report(exc: RedundikError) -> int:
    from redundik.cli._console import JSON_MODE, emit_json

    code = exit_code(exc)
    text = " ".join(str(exc).split())  # always one line, and bounded
    text = text if len(text) <= 1000 else text[:997] + "..."
    if JSON_MODE["on"]:
        emit_json({"ok": False, "error": text, "exit_code": code, "kind": type(exc).__name__})
    if is_installed("typer"):
        import typer

        typer.secho(f"error: {text}", err=True, fg=typer.colors.RED)
    else:
        print(f"error: {text}", file=sys.stderr)
    return code


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (:data:`EXIT_CODES`)."""
    from redundik.cli._console import JSON_MODE

    JSON_MODE["on"] = False
    try:
        app = _app()
        with warnings.catch_warnings():
            # numpy's floating-point warnings (overflow on hostile numbers such as a radius of 1e308) would print
            # ahead of the one-line error: every result is checked for finiteness and reported, so mute them here
            warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"numpy(\..*)?")
            warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"redundik(\..*)?")
            # a joint or frame name in a script the figure font lacks (CJK, ...) is drawn as boxes; matplotlib's
            # per-glyph warnings (two lines each, with source) would otherwise fill stderr of a successful run
            warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from font", category=UserWarning)
            code = app(args=argv, standalone_mode=False)
        # (typer turns Ctrl-C inside a command into Exit(130), which non-standalone mode returns: that was exit 0)
        if code == TYPER_INTERRUPTED:
            return _aborted()
        if isinstance(code, int) and not isinstance(code, bool) and code != EXIT_OK:
            return code
    except RedundikError as exc:
        return _report(exc)
    except KeyboardInterrupt:
        return _aborted()
    except OSError as exc:  # the file system said no (permissions, a full disk, a name too long): not a bug
        where = f" '{exc.filename}'" if getattr(exc, "filename", None) else ""
        return _report(ConfigError(f"cannot read or write{where}: {exc.strerror or exc}"))
    except Exception as exc:
        name = type(exc).__name__
        if name == "Exit":  # typer.Exit / click.exceptions.Exit
            return int(getattr(exc, "exit_code", 0) or 0)
        if name == "Abort":
            return _aborted()
        # Usage errors (missing option, bad value): typer raises click's ClickException, from the click package or
        # from the copy typer vendors (typer ≥ 0.2x), so recognise it by its interface rather than by import.
        show, code = getattr(exc, "show", None), getattr(exc, "exit_code", None)
        if callable(show) and isinstance(code, int):
            show()
            return code
        return _internal(exc)
    return EXIT_OK


def _internal(exc: Exception) -> int:
    """An unexpected exception (a bug, not bad input): one line naming it, never a bare traceback.

    ``REDUNDIK_TRACEBACK=1`` re-raises it, for a bug report.
    """
    if os.environ.get("REDUNDIK_TRACEBACK"):
        raise exc
    from redundik.cli._console import JSON_MODE, emit_json

    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    where = f" at {Path(tb.tb_frame.f_code.co_filename).name}:{tb.tb_lineno}" if tb is not None else ""
    text = " ".join(f"{type(exc).__name__}: {exc}".split())
    text = text if len(text) <= 600 else text[:597] + "..."
    text = f"internal error (a bug in redundik, please report it; REDUNDIK_TRACEBACK=1 shows it){where}: {text}"
    if JSON_MODE["on"]:
        emit_json({"ok": False, "error": text, "exit_code": EXIT_INTERNAL, "kind": type(exc).__name__})
    print(f"error: {text}", file=sys.stderr)
    return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
