"""Config's OBJ reader, below mesh_formats: an OBJ file read as exporters write it, with NumPy
(trimesh's OBJ reader loops in Python per face: most of a minute at 10^6 triangles on a busy
machine). What cannot define a triangle is skipped and counted, never refused: faces of fewer
than 3 vertices, ``l`` and ``p`` elements, and every statement that is not ``v``, ``vt``,
``f``, ``o`` or ``g`` (``vn``: file normals are never read, ``s``, ``mtllib``, ``usemtl``,
unknown keywords). Texture coordinates (``vt``, a face's ``v/vt``) are read for alpha-tested
casters, their v flipped (harness/scene/alpha.py's convention), and the ``mtllib`` files only
for their materials' ``map_d`` (a cut-out, with ``usemtl``). What stays an error names its
line: an index out of range, a vertex that is not 3 numbers, a non-finite coordinate that a
face uses.

:func:`obj_triangles` is the cheap count the budget is checked against before any parse: the
``f`` lines' triangles with polygons fanned, read in blocks of ``SCAN_BLOCK`` bytes, so its
memory is bounded whatever the file's size, and it stops once past the budget."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .limits import MAX_COORDINATE

_BLANKS = np.frombuffer(b" \t\r\n", np.uint8)
SCAN_BLOCK = 1 << 22  # 4 MiB: the cheap count's memory is a few times this
KEY_BYTES = 8  # a line's keyword is told apart by its first 8 bytes (longer ones are cut)
GEOMETRY = (b"v", b"vt", b"f", b"o", b"g")
SHORT_FACES = "faces with fewer than 3 vertices"


def _key(keyword: bytes) -> int:
    return int(np.frombuffer(keyword.ljust(KEY_BYTES, b"\0"), "<u8")[0])


def _blank(bytes_: np.ndarray) -> np.ndarray:
    return np.isin(bytes_, _BLANKS)


def _fanned(buf: np.ndarray) -> int:
    """Triangles of the ``f`` lines in ``buf`` (whole lines), polygons fanned (a face of n
    vertices is n - 2 triangles, one of fewer none)."""
    if not len(buf):
        return 0
    starts = np.r_[0, np.flatnonzero(buf[:-1] == ord("\n")) + 1]
    after = np.r_[buf, ord("\n")][starts + 1]
    face = (buf[starts] == ord("f")) & _blank(after)
    if not face.any():
        return 0
    word = ~_blank(buf)
    word_starts = (word & np.r_[True, ~word[:-1]]).view(np.uint8)
    words = np.add.reduceat(word_starts, starts, dtype=np.int64)[face]  # "f" is one of them
    return int(np.maximum(words - 3, 0).sum())


def obj_triangles(path, stop_after: int | None = None) -> int:
    """The triangles an OBJ file's faces make (polygons fanned), without parsing it: read in
    blocks, stopping once the count passes ``stop_after``."""
    total, carry = 0, b""
    with open(path, "rb") as f:
        while True:
            block = f.read(SCAN_BLOCK)
            data = carry + block
            cut = data.rfind(b"\n") + 1 if block else len(data)
            data, carry = data[:cut], data[cut:]
            total += _fanned(np.frombuffer(data, np.uint8))
            if not block or (stop_after is not None and total > stop_after):
                return total


class ObjLines:
    """An OBJ file's lines, each known by its keyword (the first word, up to 8 bytes)."""

    def __init__(self, data: bytes):
        self.data = data
        self.buf = np.frombuffer(data, np.uint8)
        newlines = np.flatnonzero(self.buf == ord("\n"))
        self.starts = np.r_[0, newlines + 1]
        self.ends = np.r_[newlines + 1, len(self.buf)]  # each line's newline included
        at = self.starts[:, None] + np.arange(KEY_BYTES)
        head = self.buf[np.minimum(at, max(len(self.buf) - 1, 0))] if len(self.buf) else \
            np.zeros(at.shape, np.uint8)
        ended = np.logical_or.accumulate(_blank(head) | (head == ord("#"))
                                         | (at >= self.ends[:, None]), axis=1)
        self.keys = np.where(ended, 0, head).astype(np.uint8).view("<u8").ravel()

    def starting(self, keyword: bytes) -> np.ndarray:
        """Indices (from 0) of the lines whose keyword is ``keyword``."""
        return np.flatnonzero(self.keys == _key(keyword))

    def skipped(self) -> dict[str, int]:
        """The statements that define no geometry, by keyword, counted (a blank line and a
        comment are not statements; a line starting with a blank is counted as ``(indented)``)."""
        other = ~np.isin(self.keys, [0, *map(_key, GEOMETRY)])
        keys, counts = np.unique(self.keys[other], return_counts=True)
        out = {np.array(k, "<u8").tobytes().rstrip(b"\0").decode("utf-8", "replace"): int(c)
               for k, c in zip(keys, counts)}
        first = self.buf[np.minimum(self.starts, max(len(self.buf) - 1, 0))]
        indented = np.flatnonzero((self.keys == 0) & np.isin(first, _BLANKS[:2]))
        if len(indented):  # rare: only these lines are looked at whole
            words = sum(bool(self.data[self.starts[i]:self.ends[i]].split()) and
                        not self.data[self.starts[i]:self.ends[i]].lstrip().startswith(b"#")
                        for i in indented)
            if words:
                out["(indented)"] = words
        return out

    def text(self, lines: np.ndarray, keyword: bytes) -> tuple[np.ndarray, np.ndarray]:
        """The bytes of these lines with their keyword blanked, and each byte's place in the
        file."""
        edge = np.zeros(len(self.buf) + 1, np.int8)
        np.add.at(edge, self.starts[lines], 1)
        np.add.at(edge, self.ends[lines], -1)
        chosen = np.flatnonzero(np.cumsum(edge[:-1], dtype=np.int8))
        text = self.buf.copy()
        for k in range(len(keyword)):
            text[self.starts[lines] + k] = ord(" ")
        return text[chosen], chosen

    def line_of(self, place: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.starts, place, side="right") - 1

    def vectors(self, keyword: bytes, what: str, columns: int = 3
                ) -> tuple[np.ndarray, np.ndarray]:
        """Line numbers (from 1) and the first ``columns`` numbers of the ``keyword`` lines."""
        lines = self.starting(keyword)
        if not len(lines):
            return lines, np.zeros((0, columns))
        text, _ = self.text(lines, keyword)
        try:
            values = np.loadtxt(text.tobytes().decode("utf-8", "replace").splitlines(),
                                usecols=tuple(range(columns)), comments="#", ndmin=2)
        except ValueError as e:
            raise ValueError(_loadtxt_problem(str(e), lines, what, columns)) from None
        return lines + 1, values

    def faces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
        """Triangles (polygons fanned) as 0-based vertex indices; each one's part, the count
        of ``o`` and ``g`` lines above it (trimesh's split_objects and split_groups); the lines
        that start parts; the faces of fewer than 3 vertices, skipped; the triangles'
        corners' 0-based ``vt`` indices, -1 where a corner names none; and each triangle's
        line."""
        lines = self.starting(b"f")
        text, place = self.text(lines, b"f")
        blank = _blank(text)
        slash = text == ord("/")
        texture_words = self._texture_words(text, blank, slash)
        if slash.any():
            # a face's texture and normal indices (after '/') are blanked: vertex indices are left
            position = np.arange(len(text), dtype=np.int32 if len(text) < 2 ** 31 else np.int64)
            after_slash = (np.maximum.accumulate(np.where(slash, position, -1))
                           > np.maximum.accumulate(np.where(blank, position, -1)))
            text[after_slash] = ord(" ")
            blank |= after_slash
        token_line = self.line_of(place[~blank & np.r_[True, blank[:-1]]])
        words = text.tobytes().split()
        try:
            index = np.array(words).astype(np.int64) if words else np.zeros(0, np.int64)
        except (ValueError, OverflowError):
            bad = next(i for i, w in enumerate(words)
                       if not re.fullmatch(rb"-?\d{1,18}", w))  # the error path only
            raise ValueError(f"line {token_line[bad] + 1}: face index "
                             f"{words[bad].decode('utf-8', 'replace')!r} is not an integer") \
                from None
        vertices = self.starting(b"v")
        before = np.searchsorted(vertices, token_line)  # vertices defined above each index
        written, index = index, np.where(index < 0, before + index, index - 1)
        bad = np.flatnonzero((index < 0) | (index >= len(vertices)))
        if len(bad):
            raise ValueError(f"line {token_line[bad[0]] + 1}: face indexes vertex "
                             f"{written[bad[0]]}, which does not exist (the file has "
                             f"{len(vertices)} vertices)")
        texture = self._texture_indices(texture_words, token_line)
        face_of_token = np.searchsorted(lines, token_line)
        counts = np.bincount(face_of_token, minlength=len(lines))
        kept = counts >= 3
        index, texture = index[kept[face_of_token]], texture[kept[face_of_token]]
        counts, lines = counts[kept], lines[kept]
        fans = counts - 2
        first = np.repeat(np.cumsum(counts) - counts, fans)
        k = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans)
        corners = np.c_[first, first + k + 1, first + k + 2]
        starts = np.union1d(self.starting(b"o"), self.starting(b"g"))
        return (index[corners], np.repeat(np.searchsorted(starts, lines), fans), starts,
                int((~kept).sum()), texture[corners], np.repeat(lines, fans))

    @staticmethod
    def _texture_words(text: np.ndarray, blank: np.ndarray, slash: np.ndarray) -> list[bytes]:
        """One word per face token: its ``vt`` index as written (between its first and second
        '/'), or ``0`` where it names none (``7``, ``7//2``)."""
        position = np.arange(len(text), dtype=np.int64)
        last_blank = np.maximum.accumulate(np.where(blank, position, -1))
        slashes = np.cumsum(slash)
        before_token = np.r_[0, slashes][last_blank + 1]  # slashes up to the token's start
        nth = slashes - before_token  # 1 from a token's first slash to its second
        out = np.where((nth == 1) & ~slash & ~blank, text, ord(" ")).astype(np.uint8)
        first_slash = slash & (nth == 1)
        following = np.r_[text[1:], ord(" ")]
        empty = first_slash & ((following == ord("/")) | _blank(following))
        out[empty] = ord("0")
        start = ~blank & np.r_[True, blank[:-1]]
        token_slashes = np.add.reduceat(slash.astype(np.int64), np.flatnonzero(start)) \
            if start.any() else np.zeros(0, np.int64)
        out[np.flatnonzero(start)[token_slashes == 0]] = ord("0")
        return out.tobytes().split()

    def _texture_indices(self, words: list[bytes], token_line: np.ndarray) -> np.ndarray:
        """The 0-based ``vt`` index of each face token (-1: none); a ValueError naming the line
        of one that is not an integer or names no ``vt`` line."""
        try:
            written = np.array(words).astype(np.int64) if words else np.zeros(0, np.int64)
        except (ValueError, OverflowError):
            bad = next(i for i, w in enumerate(words) if not re.fullmatch(rb"-?\d{1,18}", w))
            raise ValueError(f"line {token_line[bad] + 1}: texture coordinate index "
                             f"{words[bad].decode('utf-8', 'replace')!r} is not an integer") \
                from None
        texcoords = self.starting(b"vt")
        before = np.searchsorted(texcoords, token_line)
        index = np.where(written < 0, before + written, written - 1)
        bad = np.flatnonzero((written != 0) & ((index < 0) | (index >= len(texcoords))))
        if len(bad):
            raise ValueError(f"line {token_line[bad[0]] + 1}: face indexes texture coordinate "
                             f"{written[bad[0]]}, which does not exist (the file has "
                             f"{len(texcoords)} vt lines)")
        return np.where(written == 0, -1, index)

    def name(self, line: int) -> str:
        end = self.data.find(b"\n", self.starts[line])
        words = self.data[self.starts[line]:end if end >= 0 else None].decode(
            "utf-8", "replace").split(maxsplit=1)
        return words[1].strip() if len(words) > 1 else ""


def _loadtxt_problem(message: str, lines: np.ndarray, what: str, columns: int = 3) -> str:
    """loadtxt's message about a row, as the line of the OBJ file (its conversion errors count
    rows from 0, its short-row errors from 1)."""
    if (m := re.search(r"could not convert string '(.*)' to \w+ at row (\d+)", message)):
        return f"line {lines[int(m[2])] + 1}: {what} value {m[1]!r} is not a number"
    if (m := re.search(r"at row (\d+) with (\d+) columns", message)):
        return (f"line {lines[int(m[1]) - 1] + 1}: a {what} needs {columns} numbers, it has "
                f"{m[2]}")
    return f"a {what} line is not {columns} numbers ({message})"


def finite(values: np.ndarray, element) -> None:
    """A ValueError naming ``element(row)`` of the first row with a non-finite coordinate or
    one beyond +-MAX_COORDINATE."""
    bad = ~(np.abs(values) <= MAX_COORDINATE).all(axis=-1)
    if bad.any():
        row = int(np.argmax(bad))
        value = values[row][~(np.abs(values[row]) <= MAX_COORDINATE)][0]
        what = (f"is {value}" if not np.isfinite(value) else
                f"has coordinate {value:g}, beyond +-{MAX_COORDINATE:g}")
        raise ValueError(f"{element(row)} {what}")


# an OBJ's cut-outs: its materials' map_d (the mtllib files it names are read for that alone),
# each texture's alpha (or grey) at this cutoff (OBJ has none of its own; engines' default)
MAP_D_CUTOFF = 0.5
MTL_MAX_BYTES = 1 << 24
UNREADABLE_MAP_D = "map_d textures that cannot be read (their faces opaque)"
FileCutout = tuple[np.ndarray, float, str]  # a file's own cut-out: texture, cutoff, where from


def _material_cutouts(lines: ObjLines, folder: Path | None, skipped: dict[str, int]
                      ) -> dict[str, FileCutout]:
    """The cut-out of each material of the ``mtllib`` files that has a ``map_d`` (a PNG,
    relative to its .mtl file); one that cannot be read is counted in ``skipped``."""
    from .alpha_files import read_alpha_texture

    cutouts: dict[str, FileCutout] = {}
    for line in lines.starting(b"mtllib") if folder is not None else ():
        for name in lines.name(line).split():
            path = folder / name
            try:
                if not path.is_file() or path.stat().st_size > MTL_MAX_BYTES:
                    continue
                text = path.read_text("utf-8", "replace")
            except OSError:
                continue
            material = None
            for words in (row.split() for row in text.splitlines()):
                if words[:1] == ["newmtl"] and len(words) > 1:
                    material = " ".join(words[1:])
                elif words[:1] == ["map_d"] and len(words) > 1 and material is not None:
                    texture = path.parent / words[-1]  # options (-clamp on ...) come first
                    try:
                        cutouts[material] = (read_alpha_texture(texture), MAP_D_CUTOFF,
                                             f"{name}: {material}: map_d {words[-1]}")
                    except (OSError, ValueError):
                        skipped[UNREADABLE_MAP_D] = skipped.get(UNREADABLE_MAP_D, 0) + 1
    return cutouts


def _triangle_cutouts(lines: ObjLines, triangle_lines: np.ndarray,
                      cutouts: dict[str, FileCutout]) -> tuple[np.ndarray, list[FileCutout]]:
    """Per triangle, the index of its material's cut-out in the list returned (-1: none): the
    material of the last ``usemtl`` above its line."""
    used = lines.starting(b"usemtl")
    if not cutouts or not len(used):
        return np.full(len(triangle_lines), -1), []
    names = [lines.name(i) for i in used]
    chosen = sorted({n for n in names if n in cutouts})
    index = {n: k for k, n in enumerate(chosen)}
    per_usemtl = np.array([-1] + [index.get(n, -1) for n in names])
    return (per_usemtl[np.searchsorted(used, triangle_lines)],
            [cutouts[n] for n in chosen])


def read_obj(data: bytes, folder: Path | None = None
             ) -> tuple[list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None,
                                   FileCutout | None]], dict[str, int]]:
    """An OBJ file's parts (each ``o`` or ``g`` line starts one; faces above any: the first),
    each with its corners' texture coordinates (F, 3, 2), v flipped to glTF's downward
    convention, or None where a corner names no ``vt``, and its cut-out (the ``map_d`` of its
    faces' material, read from the ``mtllib`` files in ``folder``; a part whose faces use
    several is split by them); and what was skipped, counted:
    ``{SHORT_FACES: n, keyword: n, ...}``."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"not a mesh file: an OBJ is text, and byte {data[e.start]:#04x} at "
                         f"offset {e.start} is not UTF-8") from None
    lines = ObjLines(data)
    numbers, vertices = lines.vectors(b"v", "vertex")
    triangles, part, starts, short, texture, triangle_lines = lines.faces()
    uv_lines, uv = lines.vectors(b"vt", "texture coordinate", 2)
    used_uv = np.unique(texture[texture >= 0])
    finite(uv[used_uv], lambda row: f"line {uv_lines[used_uv[row]]}: texture coordinate")
    uv = np.c_[uv[:, 0], 1 - uv[:, 1]]  # an OBJ's v grows upward; glTF's (ours) downward
    used = np.flatnonzero(np.bincount(triangles.ravel(), minlength=len(vertices)))
    # a vertex no face uses may be anything
    finite(vertices[used], lambda row: f"line {numbers[used[row]]}: vertex")
    skipped = {SHORT_FACES: short} if short else {}
    skipped.update(lines.skipped())
    cut, cutouts = _triangle_cutouts(lines, triangle_lines,
                                     _material_cutouts(lines, folder, skipped))
    group = part * (len(cutouts) + 1) + cut + 1  # a part's faces apart by their cut-out
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(group[order], np.arange(group.max(initial=0) + 2))
    parts = []
    for g in np.flatnonzero(np.bincount(group)):  # per part, not per triangle
        chosen = order[bounds[g]:bounds[g + 1]]
        p, c = divmod(int(g), len(cutouts) + 1)
        corners = texture[chosen]
        name = (lines.name(starts[p - 1]) if p else "") or f"part{p}"
        split = len(np.unique(cut[part == p])) > 1
        parts.append((f"{name}:{cutouts[c - 1][2]}" if split and c else name, vertices,
                      triangles[chosen], uv[corners] if (corners >= 0).all() else None,
                      cutouts[c - 1] if c else None))
    return parts, skipped
