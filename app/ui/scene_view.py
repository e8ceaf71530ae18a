"""Draw the simulated boxes in viser, adding, moving and removing nodes as the scene changes."""

from __future__ import annotations

import math
from collections.abc import Callable

import viser

from core.scene import Box

BOX_RGB = (194, 153, 107)
DARK_BOX_RGB = (20, 20, 23)
"""A box whose surface returns no depth (`Box.dark`) is drawn black, as in the simulation."""


class SceneView:
    """Box nodes under `/scene/boxes/<id>`, kept in step with the world's boxes."""

    def __init__(self, server: viser.ViserServer, on_click: Callable[[str], None] | None = None) -> None:
        self.server = server
        self.on_click = on_click
        self._nodes: dict[str, tuple[Box, viser.BoxHandle]] = {}

    def update(self, boxes: tuple[Box, ...]) -> None:
        """Make the drawn boxes equal to `boxes` (only changed ones are sent)."""
        wanted = {b.id: b for b in boxes}
        for box_id in list(self._nodes):
            if box_id not in wanted:
                self._nodes.pop(box_id)[1].remove()
        for box_id, box in wanted.items():
            old = self._nodes.get(box_id)
            if old is not None and old[0] == box:
                continue
            if old is not None and (old[0].size, old[0].dark) == (box.size, box.dark):
                handle = old[1]
            else:
                if old is not None:
                    old[1].remove()
                colour = DARK_BOX_RGB if box.dark else BOX_RGB
                handle = self.server.scene.add_box(f"/scene/boxes/{box_id}", color=colour, dimensions=box.size)
                on_click = self.on_click
                if on_click is not None:
                    handle.on_click(lambda _, box_id=box_id, on_click=on_click: on_click(box_id))
            handle.position = box.position
            handle.wxyz = (math.cos(box.yaw / 2), 0.0, 0.0, math.sin(box.yaw / 2))
            self._nodes[box_id] = (box, handle)
