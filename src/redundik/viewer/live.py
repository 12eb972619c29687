"""Live 3-D viewer: meshcat through Pinocchio's ``MeshcatVisualizer`` (optional extra ``viewer``).

Why meshcat: Pinocchio ships its visualiser for it (the same visual ``GeometryModel`` redundik loads, DAE/STL meshes
sent as they are), the wheel is small and carries its three.js client (no CDN: the page is served by the local
meshcat server), and it is what pink and PlaCo users already watch. viser would also do (a richer GUI) but needs
its own URDF loader and a larger dependency set.

A control loop calls :meth:`LiveViewer.update` once per tick. By default the call only stores q and returns (about
a microsecond); a background thread pushes the latest q at ``rate_hz`` (each push is one ZMQ round trip per visual,
about 1–2 ms for the Panda, off the loop's thread). With ``threaded=False`` the push happens inside
:meth:`update`, rate-limited on the wall clock.

Besides the meshes: task frames and targets (triads), desired and actual paths (lines), round obstacles, and a
small sphere at each joint coloured by joint-limit proximity (grey → orange → red).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from redundik._optional import require_extra
from redundik.errors import ModelError
from redundik.kinematics.model import RobotModel
from redundik.viewer.scene import DEFAULT_COLOR, Obstacle, _package_dirs, geometry_mesh, limit_proximity

if TYPE_CHECKING:
    from rich.console import Console

    from redundik.config.loader import TaskPlan

_BUCKETS = ((0.0, 0xB8BCC4), (0.6, 0xF59A1F), (0.85, 0xE61F1A))  # proximity threshold → colour


def _bucket(p: float) -> int:
    out = 0
    for i, (lo, _) in enumerate(_BUCKETS):
        if p >= lo:
            out = i
    return out


def light_visuals(model: pin.Model, urdf: str | Path, max_triangles: int = 3000) -> pin.GeometryModel:
    """The URDF's visual geometry with every mesh decimated into an in-memory triangle mesh.

    Pinocchio's visualiser then sends triangle buffers (tens of kB) instead of the mesh files (the Panda's DAE files
    are 10 MB, which a browser takes seconds to parse).

    Raises:
        ModelError: the visual geometry cannot be loaded.
    """
    import coal

    try:
        full = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL, package_dirs=_package_dirs(Path(urdf)))
    except Exception as exc:  # pinocchio raises ValueError/RuntimeError from C++
        raise ModelError(f"could not load the visual geometry of '{urdf}': {exc}") from exc
    light = pin.GeometryModel()
    for g in full.geometryObjects:
        mesh = geometry_mesh(g.geometry, max_triangles)
        if mesh is None:
            continue
        v = mesh[0].astype(np.float64) * np.asarray(g.meshScale)
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(int(mesh[1].shape[0]), int(v.shape[0]))
        bvh.addVertices(v)
        bvh.addTriangles(mesh[1].astype(np.int64))
        bvh.endModel()
        obj = pin.GeometryObject(g.name, int(g.parentJoint), int(g.parentFrame), g.placement, bvh)
        obj.meshColor = np.array([*DEFAULT_COLOR, 1.0])
        light.addGeometryObject(obj)
    return light


class LiveViewer:
    """The robot in meshcat, updated from a control loop.

    Args:
        robot: The redundik robot.
        urdf: Its URDF (visual meshes); ``None``: frames and joint markers only.
        rate_hz: Pushes per second at most [Hz].
        zmq_url: An existing meshcat server (``meshcat-server``); ``None`` starts one.
        open_browser: Open the page in the default browser.
        threaded: Push from a background thread (the loop's call only stores q).
        frames: Frames drawn as triads (task frames).
        prefix: Root node name in the meshcat tree.
        max_triangles: Triangle budget per visual mesh (decimated: the page loads in a fraction of a second).

    Raises:
        ExtraImportError: meshcat is not installed (``pip install 'redundik[viewer]'``).
        ModelError: the URDF's visual geometry cannot be loaded.
    """

    def __init__(
        self,
        robot: RobotModel,
        urdf: str | Path | None = None,
        *,
        rate_hz: float = 30.0,
        zmq_url: str | None = None,
        open_browser: bool = False,
        threaded: bool = True,
        frames: Sequence[str] = (),
        prefix: str = "redundik",
        max_triangles: int = 3000,
    ) -> None:
        meshcat = require_extra("meshcat", "viewer")
        import meshcat.geometry as mg
        from pinocchio.visualize import MeshcatVisualizer

        self._mg = mg
        self.robot = robot
        self.model = robot.model.copy()
        self.data = self.model.createData()
        self.period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        visual = light_visuals(self.model, urdf, max_triangles) if urdf is not None else pin.GeometryModel()
        self.vis = meshcat.Visualizer(zmq_url=zmq_url)
        self.viz = MeshcatVisualizer(self.model, None, visual, data=self.data)
        self.viz.initViewer(viewer=self.vis, open=open_browser)
        self.viz.loadViewerModel(rootNodeName=prefix)
        self.root = prefix
        self.set_camera()
        self.frames = list(frames)
        for f in self.frames:
            self.vis[f"{prefix}/frames/{f}"].set_object(mg.triad(0.1))
        self._joints = [j for j in range(1, self.model.njoints) if self.model.joints[j].nq == 1]
        self._buckets: dict[int, int] = {}
        self._q: np.ndarray | None = None
        self._pushed_at = -np.inf
        self.pushes = 0
        self.push_time = 0.0
        self._lock = threading.Lock()
        self._push_lock = threading.Lock()  # one push at a time: meshcat's REQ socket breaks under two threads
        self._wake = threading.Event()
        self._stop = False
        self._failed: str | None = None  # why the background thread's last push failed (reported by update)
        self._thread: threading.Thread | None = None
        if threaded:
            self._thread = threading.Thread(target=self._worker, name="redundik-meshcat", daemon=True)
            self._thread.start()

    @property
    def url(self) -> str:
        """The page of the viewer (served by the local meshcat server)."""
        return str(self.vis.url())

    # ------------------------------------------------------------------ per tick
    def update(self, q: np.ndarray, t: float | None = None, *, force: bool = False) -> None:
        """Show configuration ``q`` (rate-limited; ``force`` pushes now, synchronously). ``t`` [s] is unused but
        accepted so loops can pass their clock.

        Raises:
            ModelError: ``q`` is not nq finite numbers, or the background thread could not show the last one.
        """
        arr = np.array(q, dtype=float)
        if arr.shape != (self.robot.nq,) or not math.isfinite(float(np.add.reduce(arr))):
            arr = self.robot.check_configuration(arr, "live viewer: update(q)")  # raises, naming what was wrong
        if self._failed is not None:
            why, self._failed = self._failed, None
            raise ModelError(f"live viewer: the background thread could not show a configuration: {why}")
        if force or self._thread is None:
            now = time.perf_counter()
            if force or now - self._pushed_at >= self.period:
                self._pushed_at = now
                with self._push_lock:
                    self._push(arr)
            return
        with self._lock:
            self._q = arr
        self._wake.set()

    def _worker(self) -> None:
        while not self._stop:
            self._wake.wait(timeout=0.5)
            self._wake.clear()
            with self._lock:
                q, self._q = self._q, None
            if q is None:
                continue
            start = time.perf_counter()
            try:
                with self._push_lock:
                    self._push(q)
            except Exception as exc:  # never die silently: the next update() reports it in the caller's thread
                self._failed = f"{type(exc).__name__}: {exc}"
            rest = self.period - (time.perf_counter() - start)
            if rest > 0:
                time.sleep(rest)

    def _push(self, q: np.ndarray) -> None:
        t0 = time.perf_counter()
        self.viz.display(q)
        pin.updateFramePlacements(self.model, self.data)
        for f in self.frames:
            self.vis[f"{self.root}/frames/{f}"].set_transform(self.data.oMf[self.model.getFrameId(f)].homogeneous)
        prox = limit_proximity(self.robot, q)
        for j in self._joints:
            b = _bucket(float(prox[j]))
            node = self.vis[f"{self.root}/limits/{self.model.names[j]}"]
            if self._buckets.get(j) != b:
                self._buckets[j] = b
                mat = self._mg.MeshLambertMaterial(color=_BUCKETS[b][1])
                node.set_object(self._mg.Sphere(0.025 if b == 0 else 0.04), mat)
            node.set_transform(self.data.oMi[j].homogeneous)
        self.push_time += time.perf_counter() - t0
        self.pushes += 1

    def flush(self, timeout: float = 2.0) -> None:
        """Wait until the background thread has pushed the last q given (no-op when not threaded)."""
        end = time.perf_counter() + timeout
        while self._thread is not None and self._q is not None and time.perf_counter() < end:
            time.sleep(0.005)
        time.sleep(self.period if self._thread is not None else 0.0)

    # ------------------------------------------------------------------ scene extras
    def set_camera(self, offset: Sequence[float] = (1.5, 1.1, 0.45)) -> None:
        """Put the camera at ``offset`` [m] from the world origin (z up), looking at it."""
        x, y, z = (float(v) for v in offset)
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])  # the camera node is y-up

    def set_visible(self, visible: bool) -> None:
        """Show or hide everything this viewer drew."""
        self.vis[self.root].set_property("visible", bool(visible))

    def set_path(self, name: str, points: np.ndarray, color: int = 0x1A9940) -> None:
        """Draw a polyline through ``points`` [m], shape (N, 3)."""
        mg = self._mg
        pts = np.asarray(points, dtype=np.float32).T
        self.vis[f"{self.root}/paths/{name}"].set_object(
            mg.Line(mg.PointsGeometry(pts), mg.LineBasicMaterial(color=color, linewidth=2))
        )

    def set_target(self, name: str, pose: np.ndarray) -> None:
        """Place a target triad at the 4×4 ``pose``."""
        node = self.vis[f"{self.root}/targets/{name}"]
        node.set_object(self._mg.triad(0.06))
        node.set_transform(np.asarray(pose, dtype=float))

    def add_obstacle(self, obstacle: Obstacle) -> None:
        """Draw a round obstacle (sphere, or a post along z)."""
        mg = self._mg
        node = self.vis[f"{self.root}/obstacles/{obstacle.name}"]
        mat = mg.MeshLambertMaterial(color=0xD9594C, opacity=0.8, transparent=True)
        if obstacle.vertical:
            node.set_object(mg.Cylinder(obstacle.height, obstacle.radius), mat)
            rot = np.eye(4)
            rot[:3, :3] = pin.utils.rotate("x", np.pi / 2)  # meshcat cylinders run along y
            rot[:3, 3] = obstacle.center
            node.set_transform(rot)
        else:
            node.set_object(mg.Sphere(obstacle.radius), mat)
            tr = np.eye(4)
            tr[:3, 3] = obstacle.center
            node.set_transform(tr)

    def close(self, stop_server: bool = True) -> None:
        """Stop the background thread and, if this viewer started it, the meshcat server."""
        self._stop = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        proc = getattr(self.vis.window, "server_proc", None)
        if stop_server and proc is not None:
            proc.terminate()
            proc.wait(timeout=5)


def replay_meshcat(
    plan: TaskPlan,
    run: str,
    t: np.ndarray,
    q: np.ndarray,
    *,
    speed: float = 1.0,
    loops: int = 1,
    console: Console | None = None,
    viewer: LiveViewer | None = None,
) -> LiveViewer:
    """Play a logged run in meshcat in real time (× ``speed``), with its paths, targets and obstacles."""
    from redundik.viewer.html import run_obstacles, run_paths

    rp = plan.runs[run]
    frames = [getattr(tk, "frame", None) for tk in rp.stack.tasks]
    v = viewer or LiveViewer(plan.robot.model, plan.robot.urdf, frames=[f for f in frames if isinstance(f, str)])
    if console is not None:
        console.print(f"meshcat viewer: {v.url}  (run '{run}', {t[-1]:.2f} s)")
    for path in run_paths(plan.robot.model, rp, t, q):
        v.set_path(f"{path.name}_desired", path.desired)
        v.set_path(f"{path.name}_actual", path.actual, color=0x2659E6)
    for ob in run_obstacles(rp):
        v.add_obstacle(ob)
    for _ in range(max(loops, 1)):
        start = time.perf_counter()
        for k in range(t.shape[0]):
            lag = t[k] / speed - (time.perf_counter() - start)
            if lag > 0:
                time.sleep(lag)
            v.update(q[k], float(t[k]))
    v.update(q[-1], force=True)
    return v


def tick_cost(viewer: LiveViewer, q: np.ndarray, ticks: int = 2000, dt: float = 0.005) -> dict[str, Any]:
    """Measure :meth:`LiveViewer.update` inside a loop of ``ticks`` at a simulated period ``dt`` [s].

    Returns the mean and max wall time of the call [µs] and the pushes made (a sleep stands in for the loop's work).
    """
    costs = np.empty(ticks)
    pushes0 = viewer.pushes
    for k in range(ticks):
        qk = q + 0.05 * np.sin(k * dt)
        t0 = time.perf_counter()
        viewer.update(qk, k * dt)
        costs[k] = time.perf_counter() - t0
        time.sleep(max(dt - costs[k], 0.0))
    viewer.flush()
    return {
        "mean_us": float(costs.mean() * 1e6),
        "p99_us": float(np.percentile(costs, 99) * 1e6),
        "max_us": float(costs.max() * 1e6),
        "pushes": viewer.pushes - pushes0,
        "push_ms": float(viewer.push_time / max(viewer.pushes, 1) * 1e3),
    }
