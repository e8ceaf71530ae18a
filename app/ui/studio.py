"""The studio page: a viser server that draws what the runtime publishes."""

from __future__ import annotations

import logging

import viser

from app.runtime import Runtime
from app.snapshot import Snapshot
from app.ui.robot_view import RobotView
from app.ui.scene_view import SceneView

log = logging.getLogger(__name__)


class Studio:
    """Binds one viser server to one runtime; every connected browser sees the same state."""

    def __init__(self, runtime: Runtime, host: str = "127.0.0.1", port: int = 8080) -> None:
        self.runtime = runtime
        self.server = viser.ViserServer(host=host, port=port, label="Perceptive HTMPC Studio")
        self.server.scene.set_up_direction("+z")
        self.server.scene.add_grid("/floor", width=14.0, height=14.0, cell_size=0.5, section_size=1.0,
                                   position=(0.0, 0.0, 0.001))
        self.robot_view = RobotView(self.server, runtime.robot)
        self.scene_view = SceneView(self.server)
        self.status = self.server.gui.add_markdown("**starting**")
        self._unsubscribe = runtime.subscribe(self.draw)
        self.draw(runtime.snapshot())

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def draw(self, snap: Snapshot) -> None:
        """Apply one snapshot to the scene, atomically for every client."""
        with self.server.atomic():
            self.robot_view.update(snap.state.q)
            self.scene_view.update(snap.boxes)
        self.status.content = f"t = {snap.state.t:6.1f} s · {len(snap.boxes)} boxes"

    def close(self) -> None:
        self._unsubscribe()
        self.server.stop()
