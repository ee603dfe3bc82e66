"""The OpenGL backend: context, framebuffers, shaders, scene buffers, pass measurement.

Import :mod:`harness.gl.context` and create a :class:`~harness.gl.context.GLContext` before any
other module here touches OpenGL: the platform must be chosen before PyOpenGL is imported.
"""
