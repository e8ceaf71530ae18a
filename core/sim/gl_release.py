"""Leave no GL context current on the calling thread, so that any other thread may render with it next.

An EGL context current on one thread cannot be made current on another (`EGL_BAD_ACCESS`) until the first
lets go of it. A camera that lets go after every render is tied to no thread: the physics thread that a
Reset starts renders with the renderers the previous one made. Making them anew every Reset (a GL context
per renderer, per new thread) grew the studio's native memory by about 0.1 MB a Reset, measured with the
contexts freed each time (issue 32; `DepthCamera.capture`).

EGL (`MUJOCO_GL=egl`) and OSMesa (`osmesa`) are handled; with any other backend this does nothing.
"""

from __future__ import annotations

import os
from collections.abc import Callable

__all__ = ["release_gl_context"]


def _egl_release() -> Callable[[], None]:
    from mujoco import egl  # after `core.sim` chose the backend: importing it needs PYOPENGL_PLATFORM=egl
    from OpenGL import EGL

    def release() -> None:
        if egl.EGL_DISPLAY is not None and EGL.eglGetCurrentContext():
            EGL.eglMakeCurrent(egl.EGL_DISPLAY, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)

    return release


def _osmesa_release() -> Callable[[], None]:
    from OpenGL import GL, osmesa

    def release() -> None:
        if osmesa.OSMesaGetCurrentContext():
            osmesa.OSMesaMakeCurrent(None, None, GL.GL_FLOAT, 0, 0)

    return release


_RELEASE: Callable[[], None] | None = None


def release_gl_context() -> None:
    """Make no GL context current on this thread (the contexts themselves live on)."""
    global _RELEASE
    if _RELEASE is None:
        backend = os.environ.get("MUJOCO_GL", "").lower()
        _RELEASE = {"egl": _egl_release, "osmesa": _osmesa_release}.get(backend, lambda: lambda: None)()
    _RELEASE()
