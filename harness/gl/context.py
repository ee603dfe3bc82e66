"""One GL context per process, on pyrender's OSMesa or EGL platform (a sweep makes it anew
between scenes' groups, :meth:`GLContext.renew`, once no GL object is alive)."""

from __future__ import annotations

import os
import sys

PLATFORMS = {"osmesa": "libosmesa6", "egl": "libegl1 libegl-mesa0 (or the NVIDIA driver)"}


class BackendError(RuntimeError):
    """The GL backend cannot start; the message says what to install."""


_current: "GLContext | None" = None


def _choose_platform(platform: str) -> None:
    if platform not in PLATFORMS:
        raise BackendError(f"unknown GL platform {platform!r}; choose one of {sorted(PLATFORMS)}")
    chosen = os.environ.get("PYOPENGL_PLATFORM")
    if "OpenGL" in sys.modules and chosen != platform:
        raise BackendError(
            f"PyOpenGL was already imported for platform {chosen!r}; cannot switch to {platform!r} "
            "in the same process"
        )
    os.environ["PYOPENGL_PLATFORM"] = platform


class GLContext:
    """A current, offscreen OpenGL 4.x core context. Rendering goes to our own FBOs."""

    def __init__(self, platform: str = "osmesa"):
        _choose_platform(platform)
        self.platform = platform
        try:
            if platform == "osmesa":
                from pyrender.platforms.osmesa import OSMesaPlatform

                self._platform = OSMesaPlatform(16, 16)
            else:
                from pyrender.platforms.egl import EGLPlatform

                self._platform = EGLPlatform(16, 16)
            self._platform.init_context()
            self._platform.make_current()
        except Exception as e:  # missing shared library surfaces as ImportError/OSError/etc.
            raise BackendError(
                f"cannot start the {platform} GL platform ({type(e).__name__}: {e}); "
                f"install the Debian package(s): {PLATFORMS[platform]}"
            ) from None
        from OpenGL import GL

        self.vendor = GL.glGetString(GL.GL_VENDOR).decode()
        self.renderer = GL.glGetString(GL.GL_RENDERER).decode()
        self.version = GL.glGetString(GL.GL_VERSION).decode()

    def make_current(self) -> None:
        self._platform.make_current()

    def renew(self) -> None:
        """Destroy the context and make a new one of the same platform, current: the driver's
        own memory goes with the old one. llvmpipe keeps, once every object of a scene's group
        is deleted, what its draws of that scene allocated (silhouette's three runs on
        instancing@1e6: 0.3 GiB, 0.17 of it C heap, the rest large blocks): only destroying
        the context gives it back. Every GL object of this process must be deleted first (a
        name kept from the old context means nothing in the new one)."""
        self._platform.delete_context()
        self._platform.init_context()
        self._platform.make_current()


def current() -> GLContext | None:
    """The process's context if one was created, else None (nothing is started)."""
    return _current


def get_context(platform: str | None = None) -> GLContext:
    """The process's context, created on first use (platform from $SHADOWBENCH_GL or osmesa)."""
    global _current
    platform = platform or os.environ["PYOPENGL_PLATFORM"]
    if _current is None:
        _current = GLContext(platform)
    elif _current.platform != platform:
        raise BackendError(f"this process already runs on {_current.platform}, not {platform}")
    _current.make_current()
    return _current
