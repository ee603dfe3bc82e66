"""shadowbench's core: it knows no technique by name."""

import os

# PyOpenGL binds its platform at first import; choose it before anything imports OpenGL.
# SHADOWBENCH_GL (osmesa | egl) wins; otherwise an explicit PYOPENGL_PLATFORM; else osmesa.
os.environ["PYOPENGL_PLATFORM"] = (os.environ.get("SHADOWBENCH_GL")
                                   or os.environ.get("PYOPENGL_PLATFORM") or "osmesa")
