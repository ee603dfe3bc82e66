"""The GL objects alive in the process's context, and what the driver still holds of deleted
ones: how a sweep checks that a scene's group released everything before the next scene.

Mesa hands out names in increasing order and never reuses one (a name deleted stays unused),
so the objects made since a moment are those named above :func:`names_now` at that moment:
:func:`live_objects` counts them by asking the context (``glIsBuffer`` ...), whoever made them
(the harness's wrappers or a technique's own ``glGen*`` calls). A name made and never bound is
no object yet (the GL spec's rule for ``glIs*``) and holds no memory: not counted.

llvmpipe keeps a reference to the textures and buffers last bound to its pipeline until the
next draw binds others, deleted or not (a 4096^2 map, 64 MiB, resident after its run was
released): :func:`drop_stale_bindings` draws one pixel so that it lets them go.
"""

from __future__ import annotations

from pathlib import Path

from OpenGL import GL

HERE = Path(__file__).parent

# kind -> (make one name, delete it, whether a name is an object of that kind)
_KINDS = {
    "buffers": (lambda: GL.glGenBuffers(1), lambda n: GL.glDeleteBuffers(1, [n]), GL.glIsBuffer),
    "textures": (lambda: GL.glGenTextures(1), lambda n: GL.glDeleteTextures(1, [n]),
                 GL.glIsTexture),
    "framebuffers": (lambda: GL.glGenFramebuffers(1), lambda n: GL.glDeleteFramebuffers(1, [n]),
                     GL.glIsFramebuffer),
    "renderbuffers": (lambda: GL.glGenRenderbuffers(1),
                      lambda n: GL.glDeleteRenderbuffers(1, [n]), GL.glIsRenderbuffer),
    "vertex arrays": (lambda: GL.glGenVertexArrays(1), lambda n: GL.glDeleteVertexArrays(1, [n]),
                      GL.glIsVertexArray),
    "queries": (lambda: GL.glGenQueries(1)[0], lambda n: GL.glDeleteQueries(1, [n]),
                GL.glIsQuery),
    "samplers": (lambda: GL.glGenSamplers(1), lambda n: GL.glDeleteSamplers(1, [n]),
                 GL.glIsSampler),
    # programs and shaders share one namespace
    "programs and shaders": (GL.glCreateProgram, GL.glDeleteProgram,
                             lambda n: GL.glIsProgram(n) or GL.glIsShader(n)),
}


def names_now() -> dict[str, int]:
    """The next name of each kind of object (one made and deleted to learn it): every object
    made from now on is named at or above it."""
    out = {}
    for kind, (make, delete, _) in _KINDS.items():
        name = int(make())
        delete(name)
        out[kind] = name
    return out


def live_objects(since: dict[str, int] | None = None) -> dict[str, int]:
    """How many objects of each kind are alive in the current context among those made since
    ``since`` (a :func:`names_now`; None: since the context began); kinds with none left out."""
    now = names_now()
    counts = {}
    for kind, (_, _, alive) in _KINDS.items():
        first = (since or {}).get(kind, 1)
        count = sum(bool(alive(name)) for name in range(first, now[kind]))
        if count:
            counts[kind] = count
    return counts


def drop_stale_bindings() -> None:
    """Draw one pixel with a program of a vertex, a geometry and a fragment stage that read
    nothing, into a framebuffer of one pixel, then restore what that changed (framebuffer 0,
    no program, the viewport): llvmpipe then lets go of the textures, buffers and
    framebuffers the last draw bound in those stages (a stage a draw does not use keeps its
    bindings: silhouette's 4096^2 maps, bound in its geometry stage, stayed with a program of
    two stages). Not the compute stage: a program once dispatched keeps the last program used
    alive after its deletion (Mesa 22), so a dispatch here would leave one behind; what the
    last dispatch bound stays until the next (the context's renewal after a group frees it).
    Everything made for it is deleted again."""
    from .framebuffer import Framebuffer
    from .geometry import FullscreenTriangle
    from .shaders import HARNESS_GLSL, Program

    viewport = [int(v) for v in GL.glGetIntegerv(GL.GL_VIEWPORT)]
    target = Framebuffer(1, 1, (GL.GL_RGBA8,), depth=False)
    program = Program(HARNESS_GLSL / "fullscreen.vert.glsl", HARNESS_GLSL / "nothing.frag.glsl",
                      geometry=HARNESS_GLSL / "pass_through.geom.glsl")
    triangle = FullscreenTriangle()
    try:
        target.bind()
        program.use()
        triangle.draw()
        GL.glFinish()
    finally:
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glUseProgram(0)
        GL.glViewport(*viewport)
        for resource in (triangle, program, target):
            resource.release()
