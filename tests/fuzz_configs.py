"""Fuzz of the shipped YAML files as a careless or hostile user would edit them (issue 9).

Run ``python -m tests.fuzz_configs [--mutants N] [--seed S]`` from the repository root (not part of the default
suite; :mod:`tests.test_fuzz_subset` runs a fast subset). Every mutant of a task file, robot config or mechanism
config is given to ``redundik validate``; valid task files are then run (``--no-figures``, at most 30 steps) and
valid mechanism configs given to one command of their kind. Counted:

* ``tracebacks`` — an exception other than a clean ``error:`` exit (exit code not 0/2, or an escaped exception);
* ``hangs`` — validate above 5 s or a command above 30 s;
* ``multiline`` — an error message on more than one line;
* ``silent`` — a run that exits 0 with a non-finite number (null) in ``summary.json``;
* ``escapes`` — a file written outside ``--out``;
* ``mismatch`` — validate accepts a file but ``run`` fails at load time (before the first step), or the reverse.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import random
import signal
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
TASKS, CONFIGS = ROOT / "tasks", ROOT / "configs"
MECHANISM_KINDS = {"stewart", "hybrid33", "delta", "mobility"}
#: Replacement values a careless or hostile user might write.
NASTY: list[Any] = [
    None, "", [], {}, "x", -1, 0, 1, 1e308, -1e308, 1e-300, 10**30, True, float("nan"), float("inf"),
    float("-inf"), "../../X", "/abs/X", "a\0b", "x" * 5000, [[[[1]]]], {"type": ["frame"]}, ["frame"], 2**70,
]  # fmt: skip


@dataclass
class Mutant:
    """One mutated file."""

    kind: str  # task | robot | mechanism
    source: str  # shipped file it comes from
    what: str  # description of the mutation
    content: str | bytes


@dataclass
class Tally:
    """Counts of a fuzz run."""

    calls: int = 0
    clean_errors: int = 0
    ok: int = 0
    problems: Counter[str] = field(default_factory=Counter)
    examples: dict[str, list[str]] = field(default_factory=dict)

    def bad(self, what: str, mutant: Mutant, detail: str) -> None:
        self.problems[what] += 1
        self.examples.setdefault(what, [])
        if len(self.examples[what]) < 5:
            self.examples[what].append(f"{mutant.source} [{mutant.what}]: {detail[:300]}")


def shipped_files() -> list[tuple[str, Path]]:
    """(kind, path) of every shipped task file, robot config and mechanism config."""
    out: list[tuple[str, Path]] = [("task", p) for p in sorted(TASKS.glob("*.yaml"))]
    for p in sorted(CONFIGS.glob("*.yaml")):
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
        out.append(("mechanism" if data.get("kind") in MECHANISM_KINDS else "robot", p))
    return out


def _absolute(kind: str, path: Path, data: dict[str, Any]) -> dict[str, Any]:
    """Make a task's robot path and a robot's urdf path absolute, so the mutant works from a temporary folder."""
    if kind == "task" and isinstance(data.get("robot"), str) and not data["robot"].startswith("example"):
        data["robot"] = str((path.parent / data["robot"]).resolve())
    if kind == "robot" and isinstance(data.get("urdf"), str) and not data["urdf"].startswith("example"):
        data["urdf"] = str((path.parent / data["urdf"]).resolve())
    return data


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _set(data: Any, path: tuple[Any, ...], value: Any) -> None:
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value


def _dump(data: Any) -> str:
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=1000)


def _bomb() -> str:
    text = 'l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
    for i in range(1, 10):
        text += f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]\n"
    return text


def mutate(kind: str, path: Path, rng: random.Random) -> Mutant:
    """One random mutant of a shipped file."""
    base = _absolute(kind, path, yaml.safe_load(path.read_text(encoding="utf-8")))
    if kind == "task" and isinstance(base.get("steps"), int):
        base["steps"] = min(base["steps"], 30)
    text = _dump(base)
    op = rng.random()
    if op < 0.12:  # text-level damage
        choice = rng.randrange(7)
        if choice == 0:
            cut = rng.randrange(len(text))
            return Mutant(kind, path.name, f"truncated at {cut}", text[:cut])
        if choice == 1:
            return Mutant(kind, path.name, "alias bomb", text + _bomb())
        if choice == 2:
            return Mutant(kind, path.name, "deep nesting", text + "zz: " + "[" * 600 + "]" * 600 + "\n")
        if choice == 3:
            return Mutant(kind, path.name, "binary", text.encode() + bytes(rng.randrange(256) for _ in range(40)))
        if choice == 4:
            return Mutant(kind, path.name, "latin-1", text.replace("name", "nämé", 1).encode("latin-1", "replace"))
        if choice == 5:
            first = text.splitlines()[0]
            return Mutant(kind, path.name, "duplicate key", text + first + "\n")
        i = rng.randrange(len(text))
        return Mutant(
            kind, path.name, "stray character", text[:i] + rng.choice(["{", "[", ":", "&", "*", "\t", "'"]) + text[i:]
        )
    data = copy.deepcopy(base)
    paths = [p for p in _paths(data) if p]
    target = rng.choice(paths)
    if op < 0.25 and isinstance(target[-1], str):  # delete a key
        node = data
        for p in target[:-1]:
            node = node[p]
        del node[target[-1]]
        return Mutant(kind, path.name, f"deleted {target}", _dump(data))
    if op < 0.32 and isinstance(target[-1], str):  # rename a key (names are keys: runs, potentials)
        node = data
        for p in target[:-1]:
            node = node[p]
        new = rng.choice(["../../X", "/abs/X", "a/b", "", "a\0b", "x" * 100, "ok_name"])
        node[new] = node.pop(target[-1])
        return Mutant(kind, path.name, f"renamed {target} to {new!r}", _dump(data))
    value = copy.deepcopy(rng.choice(NASTY))
    _set(data, target, value)
    return Mutant(kind, path.name, f"{target} = {str(value)[:40]!r}", _dump(data))


class Hang(Exception):
    """A call exceeded its time limit."""


@contextlib.contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    def fire(*_: Any) -> None:
        raise Hang

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _cli(args: list[str], limit: float) -> tuple[int | None, str, str, float]:
    """Run ``redundik ARGS`` in-process: (exit code or None on an escaped exception/hang, stdout, stderr, seconds)."""
    from redundik.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    start = time.perf_counter()
    code: int | None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _deadline(limit):
            code = main(args)
    except Hang:
        return -1, out.getvalue(), err.getvalue(), time.perf_counter() - start
    except BaseException as exc:
        return None, out.getvalue(), err.getvalue() + f"\n{type(exc).__name__}: {exc}", time.perf_counter() - start
    return code, out.getvalue(), err.getvalue(), time.perf_counter() - start


def _tree(root: Path, skip: Path) -> set[Path]:
    return {p for p in root.rglob("*") if skip not in p.parents and p != skip}


def _mechanism_command(content: str | bytes) -> list[str]:
    try:
        data = yaml.safe_load(content)
        kind = data.get("kind") if isinstance(data, dict) else None
    except Exception:
        kind = None
    return {
        "stewart": ["stewart", "ik", "--p", "0", "0", "1"],
        "hybrid33": ["hybrid33", "ik", "--p", "0", "0", "1"],
        "delta": ["delta", "ik", "--top", "0", "0", "-1"],
    }.get(str(kind), ["mobility"])


def check(mutant: Mutant, work: Path, tally: Tally) -> None:
    """Validate (and run) one mutant, counting what went wrong."""
    folder = Path(tempfile.mkdtemp(dir=work))
    f = folder / "sub" / "mutant.yaml"
    f.parent.mkdir()
    (f.write_bytes if isinstance(mutant.content, bytes) else f.write_text)(mutant.content)  # type: ignore[operator]
    out = folder / "sub" / "out"
    before = _tree(folder, out)
    code, _, err, secs = _cli(["validate", str(f)], 5.0)
    tally.calls += 1
    valid = _judge(mutant, tally, code, err, secs, 5.0)
    if mutant.kind == "task":
        rcode, _, rerr, rsecs = _cli(["run", str(f), "--out", str(out), "--no-figures", "--quiet"], 30.0)
        tally.calls += 1
        ran = _judge(mutant, tally, rcode, rerr, rsecs, 30.0)
        load_time = rcode == 3
        if valid and load_time:
            tally.bad("mismatch", mutant, f"validate ok, run failed at load: {rerr.strip()}")
        if not valid and ran:
            tally.bad("mismatch", mutant, "validate failed, run succeeded")
        if ran:
            summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
            if _has_null(summary["runs"]):
                tally.bad("silent", mutant, "exit 0 with a non-finite value in summary.json")
    elif mutant.kind == "mechanism" and valid:
        ccode, _, cerr, csecs = _cli([*_mechanism_command(mutant.content), str(f)], 30.0)
        tally.calls += 1
        _judge(mutant, tally, ccode, cerr, csecs, 30.0)
    if _tree(folder, out) != before:
        tally.bad("escapes", mutant, f"new files: {sorted(map(str, _tree(folder, out) - before))[:3]}")


def _has_null(node: Any) -> bool:
    if node is None:
        return True
    if isinstance(node, dict):
        return any(_has_null(v) for v in node.values())
    if isinstance(node, list):
        return any(_has_null(v) for v in node)
    return False


def _judge(mutant: Mutant, tally: Tally, code: int | None, err: str, secs: float, limit: float) -> bool:
    """Count one call; True if it succeeded."""
    if code == -1:
        tally.bad("hangs", mutant, f"> {limit} s")
        return False
    if code is None or code not in (0, 3, 4) or "Traceback" in err:
        tally.bad("tracebacks", mutant, err.strip().splitlines()[-1] if err.strip() else f"exit {code}")
        return False
    if code in (3, 4):  # invalid input, run failure
        tally.clean_errors += 1
        if err.count("\n") != 1 or not err.startswith("error: "):
            tally.bad("multiline", mutant, err)
        return False
    tally.ok += 1
    return True


def fuzz(n: int, seed: int, work: Path) -> Tally:
    """``n`` mutants spread over every shipped file, from a fixed seed."""
    rng = random.Random(seed)
    files = shipped_files()
    tally = Tally()
    for i in range(n):
        kind, path = files[i % len(files)]
        check(mutate(kind, path, rng), work, tally)
    return tally


def main() -> int:
    """Command line: print the counts; exit code 1 if any problem was found."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mutants", type=int, default=600)
    parser.add_argument("--seed", type=int, default=9)
    args = parser.parse_args()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tally = fuzz(args.mutants, args.seed, Path(tmp))
    print(
        f"{args.mutants} mutants, {tally.calls} calls in {time.perf_counter() - start:.0f} s: "
        f"{tally.clean_errors} clean one-line errors, {tally.ok} successes"
    )
    for what in ("tracebacks", "hangs", "multiline", "silent", "escapes", "mismatch"):
        print(f"  {what}: {tally.problems[what]}")
        for ex in tally.examples.get(what, []):
            print(f"      {ex}")
    return 1 if sum(tally.problems.values()) else 0


if __name__ == "__main__":
    raise SystemExit(main())
