"""Simulated depth cameras: MuJoCo off-screen depth renders turned into `DepthFrame`s.

Depth is planar (along the optical axis) in metres; pixels beyond `range_m` or nearer than `near_m`
read 0 ("no return"), as real depth cameras report. Optional noise grows with depth squared, as for
a stereo camera: std = noise_std_m · (z / 1 m)².
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from core.params import CameraParams
from core.sim.world import SimWorld
from core.types import DepthFrame


def intrinsics(params: CameraParams) -> np.ndarray:
    """Pinhole K for the render: square pixels, principal point at the image centre (pixel centres)."""
    f = 0.5 * params.height_px / math.tan(math.radians(params.fovy_deg) / 2)
    return np.array([[f, 0.0, (params.width_px - 1) / 2], [0.0, f, (params.height_px - 1) / 2], [0.0, 0.0, 1.0]])


class DepthCamera:
    """One camera of the world (`hand` or `base`); renders from the thread that created nothing else GL."""

    def __init__(self, world: SimWorld, name: str, params: CameraParams, seed: int = 0) -> None:
        self.world = world
        self.name = name
        self.params = params
        self.K = intrinsics(params)
        self._rng = np.random.default_rng(seed)
        self._renderer: mujoco.Renderer | None = None
        self._seg_renderer: mujoco.Renderer | None = None
        self._version = -1
        self._options = mujoco.MjvOption()

    def _ensure(self) -> None:
        if self._renderer is not None and self._version == self.world.model_version:
            return
        self.close()
        m = self.world.model
        m.cam_fovy[m.camera(f"camera_{self.name}").id] = self.params.fovy_deg
        self._renderer = mujoco.Renderer(m, self.params.height_px, self.params.width_px)
        self._renderer.enable_depth_rendering()
        self._version = self.world.model_version

    def render(self) -> DepthFrame:
        """Render the current scene as a `DepthFrame` stamped with sim time."""
        with self.world.lock:
            self._ensure()
            self._renderer.update_scene(self.world.data, camera=f"camera_{self.name}", scene_option=self._options)
            depth = self._renderer.render().astype(np.float64)
            T = self.world.robot.camera_pose(self.world.state().q, self.name)
            t = self.world.time
        no_return = (depth > self.params.range_m) | (depth < self.params.near_m)
        if self.params.noise_std_m > 0.0:  # noise on real returns only: the sky at 50 m must not land in range
            depth = depth + self._rng.normal(0.0, 1.0, depth.shape) * self.params.noise_std_m * depth**2
            no_return |= (depth > self.params.range_m) | (depth < self.params.near_m)
        depth[no_return] = 0.0
        return DepthFrame(t=t, camera=self.name, depth=depth.astype(np.float32), K=self.K.copy(),
                          T_world_camera=T, range_m=self.params.range_m)

    def render_box_ids(self) -> np.ndarray:
        """Ground-truth segmentation (tests only): per pixel the box id, '' for anything else."""
        with self.world.lock:
            if self._seg_renderer is None or self._version != self.world.model_version:
                self._ensure()
                self._seg_renderer = mujoco.Renderer(self.world.model, self.params.height_px, self.params.width_px)
                self._seg_renderer.enable_segmentation_rendering()
            self._seg_renderer.update_scene(self.world.data, camera=f"camera_{self.name}",
                                            scene_option=self._options)
            seg = self._seg_renderer.render()
            geom_types = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
            lookup = {int(g): self.world.box_id_of_geom(int(g)) or "" for g in np.unique(seg[..., 0][geom_types])}
        out = np.full(seg.shape[:2], "", dtype=object)
        for g, box_id in lookup.items():
            out[geom_types & (seg[..., 0] == g)] = box_id
        return out

    def close(self) -> None:
        """Free the GL resources."""
        for r in (self._renderer, self._seg_renderer):
            if r is not None:
                r.close()
        self._renderer = self._seg_renderer = None
