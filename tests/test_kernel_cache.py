"""Numba's on-disk cache of the kernels lives in a folder named by a stamp of every source they are compiled from
(redundik._kernel_cache): a change to a module whose kernels or constants another kernel module compiles in starts
a new folder, so that nothing is loaded stale."""

from __future__ import annotations

import ast
import shutil
from pathlib import Path
from typing import Any

from redundik import _kernel_cache as kc

SRC = kc.PACKAGE_ROOT


def _compiled_modules() -> set[str]:
    """The package's files that define compiled functions (``numba.njit`` / the kernels' ``_jit``)."""
    out = set()
    for path in SRC.rglob("*.py"):
        text = path.read_text()
        if "@_jit" in text or "nb.njit(" in text:
            out.add(path.relative_to(SRC).as_posix())
    return out


def _redundik_imports(rel: str) -> set[str]:
    """The package's modules a file imports names from (``from redundik.x.y import ...``), as file paths."""
    tree = ast.parse((SRC / rel).read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("redundik."):
            parts = node.module.split(".")[1:]
            path = "/".join(parts) + ".py"
            if (SRC / path).exists():
                out.add(path)
    return out


def test_the_stamp_covers_every_kernel_module_and_what_it_imports() -> None:
    compiled = _compiled_modules()
    assert {"resolvers/kernels.py", "resolvers/hqp_kernels.py", "resolvers/fused_kernels.py"} <= compiled
    needed = set(compiled)
    for rel in compiled:
        needed |= _redundik_imports(rel)
    needed.discard("_kernel_cache.py")
    missing = needed - set(kc.KERNEL_SOURCES)
    assert not missing, f"add to KERNEL_SOURCES: {sorted(missing)}"


def test_the_kernels_are_cached_in_the_stamped_folder() -> None:
    from redundik.collision import kernels as ck
    from redundik.resolvers import hqp_fused, hqp_kernels, kernels

    folder = str(kc.cache_dir())
    assert kc.cache_dir().name == f"kernels-{kc.sources_stamp()}"
    for fn in (kernels.in_box, hqp_kernels.closed_step, hqp_fused.fused_hqp_step, ck.__dict__[_first_jit(ck)]):
        assert fn._cache._impl.locator.get_cache_path().startswith(folder)
        assert kc.KERNELS[fn.py_func.__module__][fn.py_func.__name__] is fn


def test_every_kernel_is_made_by_the_cache_aware_decorator() -> None:
    """A kernel decorated by ``numba.njit`` directly would be cached beside its source (a read-only site-packages:
    numba's own folder) and stamped with its own file only."""
    offenders = []
    for path in SRC.rglob("*.py"):
        if path.name != "_kernel_cache.py" and ("njit(" in path.read_text() or "@nb.jit" in path.read_text()):
            offenders.append(path.relative_to(SRC).as_posix())
    assert not offenders, f"use redundik._kernel_cache.jit in {offenders}"


def _first_jit(module: object) -> str:
    return next(k for k, v in vars(module).items() if hasattr(v, "_cache") and hasattr(v, "py_func"))


def test_a_change_to_a_dependency_changes_the_stamp(tmp_path: Path) -> None:
    for rel in kc.KERNEL_SOURCES:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(SRC / rel, tmp_path / rel)
    before = kc.sources_stamp(tmp_path)
    kc._stamps.clear()
    assert kc.sources_stamp(tmp_path) == before  # deterministic
    kc._stamps.clear()
    dep = tmp_path / "resolvers/hqp_kernels.py"  # a module hqp_fused compiles in, not hqp_fused itself
    dep.write_text(dep.read_text() + "\n# edited\n")
    after = kc.sources_stamp(tmp_path)
    assert after != before
    assert after != kc.sources_stamp(SRC)


def test_a_namespace_waits_for_an_import_another_thread_has_under_way(tmp_path: Path, monkeypatch: Any) -> None:
    """A kernel namespace read while another thread (the cold start's compiling one) is still importing its module
    gets the module once made, not the half-made one in ``sys.modules`` (an ``AttributeError``, "partially
    initialized module", in the benchmark's cold-start case before)."""
    import importlib
    import sys
    import threading
    import time

    (tmp_path / "slow_kernels_for_test.py").write_text("import time\ntime.sleep(0.5)\nanswer = 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "slow_kernels_for_test", raising=False)
    importer = threading.Thread(target=importlib.import_module, args=("slow_kernels_for_test",))
    importer.start()
    while "slow_kernels_for_test" not in sys.modules:  # (the other thread's import under way)
        time.sleep(0.001)
    try:
        assert kc.KernelNamespace("slow_kernels_for_test").answer == 42
    finally:
        importer.join()
        sys.modules.pop("slow_kernels_for_test", None)
