"""PlaCo as a peer, out of process: find a PlaCo interpreter, start :mod:`placo_worker` in it, drive it by chunks.

PlaCo 0.10 pins ``pin==3.8.0``, so it lives in its own environment (``pip install 'redundik[placo]'`` there, or
just ``placo numpy``)::

    python3 -m venv .venv-placo && .venv-placo/bin/pip install placo numpy

The interpreter is, in order: ``--placo-python PATH``, the environment variable ``REDUNDIK_PLACO_PYTHON``, or
``.venv-placo/bin/python`` in the checkout. Without one the PlaCo cases are listed as skipped.

The worker gets the scenario's URDF with ``<visual>``/``<collision>`` stripped, the same frames, q0, posture weight
and gain and the URDF's joint and velocity limits; per chunk the reference poses at t + dt; it returns per-step
times and the configurations, which the common ruler (:class:`benchmarks.bench.runners.Metrics`) measures on
redundik's model like every other method's.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.bench.peer_runners import _PeerRunner
from benchmarks.bench.scenarios import POSTURE_GAIN, POSTURE_WEIGHT, Scenario, urdf_path

WORKER = Path(__file__).resolve().with_name("placo_worker.py")
CHECKOUT = Path(__file__).resolve().parents[2]
ENV_VAR = "REDUNDIK_PLACO_PYTHON"


def find_placo_python(explicit: str | os.PathLike[str] | None = None) -> tuple[str | None, str]:
    """(interpreter, where it came from) or (``None``, why not): ``explicit``, ``$REDUNDIK_PLACO_PYTHON``, or the
    checkout's ``.venv-placo``; the interpreter must import placo."""
    candidates: list[tuple[str, str]] = []
    if explicit:
        candidates.append((str(explicit), "--placo-python"))
    if os.environ.get(ENV_VAR):
        candidates.append((os.environ[ENV_VAR], ENV_VAR))
    candidates.append((str(CHECKOUT / ".venv-placo" / "bin" / "python"), ".venv-placo"))
    reasons = []
    for path, origin in candidates:
        if not Path(path).is_file():
            reasons.append(f"{origin}: {path} does not exist")
            continue
        probe = subprocess.run([path, "-c", "import placo, numpy"], capture_output=True, text=True, timeout=120)
        if probe.returncode == 0:
            return path, origin
        reasons.append(f"{origin}: {path} cannot import placo")
    return None, "no PlaCo interpreter (" + "; ".join(reasons) + "); see docs/benchmark.md"


class PlacoWorker:
    """The worker process: one JSON line per request and per answer."""

    def __init__(self, python: str) -> None:
        self._stderr = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(
            [python, str(WORKER)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr, text=True
        )

    def request(self, msg: dict[str, Any]) -> dict[str, Any]:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(msg) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            self._stderr.seek(0)
            raise RuntimeError("PlaCo worker exited: " + self._stderr.read()[-400:])
        out: dict[str, Any] = json.loads(line)
        if not out.get("ok"):
            raise RuntimeError(f"PlaCo worker: {out.get('error')}")
        return out

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
                self.proc.stdin.flush()
                self.proc.wait(timeout=10)
            except Exception:
                self.proc.kill()
        self._stderr.close()


class PlacoRunner(_PeerRunner):
    """PlaCo's ``KinematicsSolver`` on the scenario's URDF: frame tasks ``soft`` (weights 1, 1), the joints task as
    the posture (weight 0.01, target q + K_p·dt·(q0 − q) each tick), joint and velocity limits, base masked unless
    the scenario floats it. Its frame task is position-level (it closes the whole error in one step): given the
    reference of t + dt it asks J Δq = p_d(t + dt) − p(t), the peers' and our K = 1/dt dead-beat task."""

    method = "placo"

    def __init__(self, scenario: Scenario, python: str) -> None:
        self.python = python
        super().__init__(scenario, "qpmad")

    def _build(self) -> None:
        from redundik.simulation.mujoco_model import strip_urdf

        sc = self.scenario
        if sc.urdf is None:
            raise RuntimeError(f"scenario '{sc.key}' has no URDF for PlaCo")
        self._dir = tempfile.TemporaryDirectory(prefix="redundik-placo-")
        urdf = Path(self._dir.name) / "robot.urdf"
        urdf.write_text(strip_urdf(urdf_path(sc)))
        self.free_flyer = bool(sc.urdf[1])
        self.joint_names = [j.name for j in self.robot.joints if j.idx_q >= 0 and j.kind != "other"]
        self.joint_idx = np.array([self.robot.joint(n).idx_q for n in self.joint_names], dtype=int)
        self.worker = PlacoWorker(self.python)
        info = self.worker.request(
            {
                "cmd": "init",
                "urdf": str(urdf),
                "frames": [f.frame for f in sc.frames],
                "free_flyer": self.free_flyer,
                "dt": sc.dt,
                "joints": self.joint_names,
                "q0": sc.q0[self.joint_idx].tolist(),
                "base": sc.q0[:7].tolist() if self.free_flyer else None,
                "frame_weights": [1.0, 1.0],
                "posture_weight": POSTURE_WEIGHT,
                "posture_gain": POSTURE_GAIN,
            }
        )
        self.version = str(info.get("placo", "?"))

    def _reset_peer(self) -> None:
        if self.k != 0 or self.scenario.episode is not None:
            raise RuntimeError("PlaCo runs continuous scenarios only")

    def _step(self, t: float) -> tuple[int, np.ndarray]:  # pragma: no cover - run() drives whole chunks
        raise NotImplementedError

    def run(self, steps: int) -> None:
        """One chunk in the worker, then the common ruler on each configuration it returned."""
        sc = self.scenario
        ts = [(self.k + i) * sc.dt for i in range(steps)]
        targets = []
        for t in ts:
            poses = [ref.trajectory.sample(t + sc.dt)[0].homogeneous.ravel() for ref in self.refs]
            targets.append(np.concatenate(poses).tolist())
        out = self.worker.request({"cmd": "run", "targets": targets})
        for t, ns, qp in zip(ts, out["ns"], out["q"], strict=True):
            q_next = self.q.copy()
            vals = np.asarray(qp, dtype=float)
            if self.free_flyer:
                q_next[:7], vals = vals[:7], vals[7:]
            q_next[self.joint_idx] = vals
            self.record_step(t, int(ns), q_next)

    def close(self) -> None:
        self.worker.close()
        self._dir.cleanup()
