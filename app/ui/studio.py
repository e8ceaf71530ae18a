"""The studio page: one viser server drawing what the runtime publishes, with panels for run
control, authoring, scene edits and monitoring. Every connected browser sees the same state."""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

from app.recording.replay import ReplaySource
from app.runtime import Runtime
from app.runtime.snapshot import Snapshot
from app.ui.access import PageAccess, guarded_viser_server
from app.ui.anchor_panel import AnchorPanel
from app.ui.authoring_panel import AuthoringPanel
from app.ui.map_view import MapView
from app.ui.monitor_panel import MonitorPanel
from app.ui.notify import notify_all
from app.ui.plan_view import PlanView
from app.ui.pose_view import PoseView
from app.ui.problems_panel import ProblemsPanel
from app.ui.progress_panel import ProgressPanel
from app.ui.robot_view import RobotView
from app.ui.run_panel import RunPanel
from app.ui.scene_panel import ScenePanel
from app.ui.scene_view import SceneView
from app.ui.timeline_panel import TimelinePanel

log = logging.getLogger(__name__)

LAYERS = {"objects": "Mapped objects", "voxels": "Map voxels", "edf": "EDF slice", "spheres": "Collision spheres",
          "frusta": "Camera frusta", "clouds": "Depth point clouds"}


@dataclass(frozen=True)
class ViewSettings:
    """How much the browser has to draw. The defaults suit software WebGL (a browser without a GPU, as
    Debian's chromium in a VM): `python -m bench.studio_fps` measures the frame rate against the detailed view."""

    robot_meshes: str = "collision"
    """'collision' (the UR10's 5.8k-triangle meshes) or 'visual' (116k triangles)."""
    shadows: bool = False
    environment_map: bool = False
    """viser's image-based lighting ('warehouse'); without it the default lights alone."""


DETAILED_VIEW = ViewSettings(robot_meshes="visual", shadows=True, environment_map=True)


class Studio:
    """Binds one viser server to one runtime."""

    def __init__(self, runtime: Runtime | ReplaySource, host: str = "127.0.0.1", port: int = 8080,
                 require_token: bool = False, view: ViewSettings = ViewSettings()) -> None:
        """`require_token`: the page needs the printed access link even on this machine (a real robot);
        listening beyond this machine always needs it (`app.ui.access`)."""
        self.runtime = runtime
        self.access = PageAccess.for_binding(host, require_token)
        self.server = guarded_viser_server(self.access, host=host, port=port, label="Perceptive HTMPC Studio")
        self.server.gui.configure_theme(control_width="large", show_logo=False)
        self.server.scene.set_up_direction("+z")
        self.server.scene.configure_default_lights(cast_shadow=view.shadows)
        if not view.environment_map:  # a hemisphere light instead: the sides of boxes stay readable, at no cost
            self.server.scene.configure_environment_map(None)
            self.server.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255),
                                                   ground_color=(210, 200, 190), intensity=1.7)
        self.server.scene.add_grid("/floor", width=16.0, height=16.0, cell_size=0.5, section_size=1.0,
                                   position=(0.0, 0.0, 0.001))
        self.server.initial_camera.position = (-2.5, -4.5, 4.0)
        self.server.initial_camera.look_at = (1.5, 0.0, 0.3)
        self._draw_lock = threading.Lock()
        self._pending_lock = threading.Lock()
        self._latest: Snapshot | None = None
        self._messages: list[str] = []
        self.robot_view = RobotView(self.server, runtime.robot, meshes=view.robot_meshes)
        self.map_view = MapView(self.server, runtime.robot, runtime.config.mapping)
        self.plan_view = PlanView(self.server)
        self.pose_view = PoseView(self.server, runtime.robot.params.base_size_m)
        self.progress = ProgressPanel(self.server)
        self.problems = ProblemsPanel(self.server)
        self.monitor = MonitorPanel(self.server)
        self.run_panel = RunPanel(self.server, runtime)
        self.timeline = None
        if isinstance(runtime, ReplaySource):
            self.timeline = TimelinePanel(self.server, runtime, self.monitor)
            self.run_panel.hide_controls()
        tabs = self.server.gui.add_tab_group()
        with tabs.add_tab("Sequence"):
            self.authoring = AuthoringPanel(self.server, runtime)
            self.map_view.fixed_labels = lambda: self.authoring.goal_labels
        with tabs.add_tab("Scene edits"):
            self.scene_panel = ScenePanel(self.server, runtime)
        with tabs.add_tab("Monitor"):
            self.monitor.build_plots()
        with tabs.add_tab("Names"):
            self.anchor_panel = AnchorPanel(self.server, runtime)
        with tabs.add_tab("Problems"):
            self.problems.build_table()
        with tabs.add_tab("View"):
            for key, label in LAYERS.items():
                box = self.server.gui.add_checkbox(label, self.map_view.show[key])
                box.on_update(lambda e, key=key: self.map_view.set_layer(key, e.target.value))
        self.scene_view = SceneView(self.server, on_click=self.scene_panel.select_box)
        self.draws = 0
        self._unsubscribe = runtime.subscribe(self.draw)
        self.draw(runtime.snapshot())

    @property
    def url(self) -> str:
        """The page's address; with a token, the access link (it sets a cookie and drops the token)."""
        base = f"http://{self.server.get_host()}:{self.server.get_port()}"
        return base if self.access.token is None else f"{base}/?token={self.access.token}"

    def draw(self, snap: Snapshot) -> None:
        """Apply a snapshot to every view and panel; a drawing error is reported, not fatal.

        While a draw is under way, newer snapshots wait as one (the latest, with every message since): the last
        snapshot is always drawn (a paused replay's seek, the final state) and no notice is lost."""
        with self._pending_lock:
            self._messages.extend(snap.messages)
            self._latest = snap
        while self._latest is not None and self._draw_lock.acquire(blocking=False):
            try:
                with self._pending_lock:
                    snap, self._latest = self._latest, None
                    messages, self._messages = self._messages, []
                if snap is not None:
                    self._draw_one(snap, messages)
            finally:
                self._draw_lock.release()

    def _draw_one(self, snap: Snapshot, messages: list[str]) -> None:
        try:
            with self.server.atomic():
                self.robot_view.update(snap.state.q)
                self.scene_view.update(snap.boxes)
                self.map_view.update(snap)
                self.plan_view.update(snap)
                self.pose_view.update(snap)
            self.progress.update(snap)
            self.problems.update(snap)
            self.monitor.update(snap)
            self.run_panel.update(snap)
            if self.timeline is not None:
                self.timeline.update(snap)
            self.scene_panel.update(snap)
            self.authoring.update(snap)
            self.anchor_panel.update(snap)
            for message in messages:
                title = "Emergency stop" if message.startswith("emergency stop") else "Runtime"
                notify_all(self.server, title, message)
            self.draws += 1
        except Exception:
            log.exception("drawing a snapshot failed")

    def close(self) -> None:
        self._unsubscribe()
        self.server.stop()
