"""Choose MuJoCo's off-screen OpenGL backend before `mujoco` is imported: EGL, else OSMesa.

MuJoCo fixes its backend from `MUJOCO_GL` when it is first imported, so we decide here, once per
process, by trying EGL in a short child process (a failed EGL init can abort the interpreter).
A user never sets `MUJOCO_GL` by hand; one who does is respected.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys

from core.errors import StudioError

log = logging.getLogger(__name__)


class GLBackendError(StudioError, RuntimeError):
    """No off-screen OpenGL backend works for MuJoCo (the message names the Debian packages to install)."""

_PROBE = "import mujoco; c = mujoco.GLContext(8, 8); c.make_current(); c.free(); print('ok')"


def _works(backend: str) -> bool:
    env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return out.returncode == 0 and out.stdout.strip().endswith("ok")


def choose_gl_backend() -> str:
    """Set `MUJOCO_GL` (and `PYOPENGL_PLATFORM`) to a backend that renders here; return its name."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    if "mujoco" in sys.modules:
        log.warning("mujoco was imported before the GL backend was chosen; rendering may fail")
    for backend in ("egl", "osmesa"):
        if _works(backend):
            os.environ["MUJOCO_GL"] = backend
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
            log.info("MuJoCo off-screen rendering through %s", backend)
            return backend
    raise GLBackendError(
        "No off-screen OpenGL for MuJoCo: EGL and OSMesa both failed. "
        "Install Debian's libegl1 and libgl1-mesa-dri (EGL) or libosmesa6 (OSMesa)."
    )
