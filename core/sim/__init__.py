"""The MuJoCo world: robot, boxes, depth cameras, odometry, scene edits, ground truth.

The off-screen GL backend is chosen before any submodule imports `mujoco`.
"""

from core.sim.gl_backend import choose_gl_backend

choose_gl_backend()
