"""GLSL programs from .glsl files, with ``#include "file.glsl"`` and ``#define`` injection."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from OpenGL import GL

from ..machine.file_stamps import stamp, stamps

GLSL_VERSION = "#version 430 core"
HARNESS_GLSL = Path(__file__).parent / "glsl"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)


class ShaderError(RuntimeError):
    """A shader did not compile or link; the message carries the driver's log."""


def _resolve(name: str, here: Path) -> Path:
    for folder in (here, HARNESS_GLSL):
        if (folder / name).is_file():
            return (folder / name).resolve()
    raise ShaderError(f"GLSL include {name!r} not found beside {here} or in {HARNESS_GLSL}")


def preprocess(path: Path, defines: dict | None = None) -> str:
    """Source of ``path`` with includes expanded (each once) and defines prepended.

    Kept for the process while none of the files it read changed (modification time, size,
    inode): a technique's programs are made anew for each run, and reading and expanding their
    files took 45 % of making a program (12 of the technique tests' 27 s in programs)."""
    header = [GLSL_VERSION] + [f"#define {k} {v}" for k, v in (defines or {}).items()]
    return "\n".join(header) + "\n#line 1\n" + _expanded(Path(path))


def _expanded(path: Path) -> str:
    known = _sources.get(path)
    if known is not None and stamps(known[0]) == known[1]:
        return known[2]
    seen: list[Path] = []
    read: list[tuple] = []

    def expand(p: Path) -> str:
        if p in seen:
            return ""
        seen.append(p)
        read.append(stamp(p))  # before reading: a file changed after is read again next time
        return _INCLUDE.sub(lambda m: expand(_resolve(m.group(1), p.parent)), p.read_text())

    text = expand(path)
    _sources[path] = (seen, tuple(read), text)
    return text


# a shader file -> (the files its expansion read, their stamps, the expansion)
_sources: dict[Path, tuple[list[Path], tuple, str]] = {}


def _compile(kind, source: str, label: str) -> int:
    shader = GL.glCreateShader(kind)
    GL.glShaderSource(shader, source)
    GL.glCompileShader(shader)
    if not GL.glGetShaderiv(shader, GL.GL_COMPILE_STATUS):
        log = GL.glGetShaderInfoLog(shader).decode(errors="replace").strip()
        GL.glDeleteShader(shader)
        raise ShaderError(f"{label} did not compile: {' | '.join(log.splitlines())}")
    return shader


class Program:
    """A linked program; :meth:`set` uploads uniforms by name and numpy shape."""

    def __init__(self, vertex: Path, fragment: Path, defines: dict | None = None,
                 geometry: Path | None = None):
        stages = [(GL.GL_VERTEX_SHADER, vertex), (GL.GL_FRAGMENT_SHADER, fragment)]
        if geometry is not None:
            stages.append((GL.GL_GEOMETRY_SHADER, geometry))
        self._link(stages, defines, f"{Path(vertex).name}+{Path(fragment).name}")

    def _link(self, stages, defines: dict | None, label: str) -> None:
        shaders = []
        try:  # a failed stage must not leave the stages compiled before it alive
            for kind, path in stages:
                shaders.append(_compile(kind, preprocess(path, defines), Path(path).name))
            self.id = GL.glCreateProgram()
            for s in shaders:
                GL.glAttachShader(self.id, s)
            GL.glLinkProgram(self.id)
        finally:
            for s in shaders:
                GL.glDeleteShader(s)
        if not GL.glGetProgramiv(self.id, GL.GL_LINK_STATUS):
            log = GL.glGetProgramInfoLog(self.id).decode(errors="replace").strip()
            GL.glDeleteProgram(self.id)
            raise ShaderError(f"{label} did not link: {log}")
        self._locations: dict[str, int] = {}

    def use(self) -> "Program":
        GL.glUseProgram(self.id)
        return self

    def location(self, name: str) -> int:
        if name not in self._locations:
            self._locations[name] = GL.glGetUniformLocation(self.id, name)
        return self._locations[name]

    def set(self, **uniforms) -> "Program":
        """Set uniforms on this (bound) program. Unused uniforms are ignored, as GL does.
        NumPy unsigned integers set ``uint`` uniforms, other integers and bools ``int`` and
        ``bool`` ones."""
        for name, value in uniforms.items():
            loc = self.location(name)
            if loc < 0:
                continue
            if isinstance(value, np.unsignedinteger):
                GL.glUniform1ui(loc, int(value))
                continue
            if isinstance(value, (bool, int, np.integer)):
                GL.glUniform1i(loc, int(value))
                continue
            a = np.asarray(value, dtype=np.float32)
            match a.shape:
                case ():
                    GL.glUniform1f(loc, float(a))
                case (2,):
                    GL.glUniform2f(loc, *a)
                case (3,):
                    GL.glUniform3f(loc, *a)
                case (4,):
                    GL.glUniform4f(loc, *a)
                case (3, 3):
                    GL.glUniformMatrix3fv(loc, 1, GL.GL_TRUE, a)
                case (4, 4):
                    GL.glUniformMatrix4fv(loc, 1, GL.GL_TRUE, a)
                case (count, 4, 4):  # a mat4 array
                    GL.glUniformMatrix4fv(loc, count, GL.GL_TRUE, a)
                case _:
                    raise ValueError(f"uniform {name}: unsupported shape {a.shape}")
        return self

    def release(self) -> None:
        GL.glDeleteProgram(self.id)


class ComputeProgram(Program):
    """A program of one compute shader (GL 4.3)."""

    def __init__(self, compute: Path, defines: dict | None = None):
        self._link([(GL.GL_COMPUTE_SHADER, compute)], defines, Path(compute).name)
