"""Per-triangle shadow volumes tested against a hierarchy of view samples (Sintorn, Olsson,
Assarsson 2011), of screen tiles or of view-sample clusters (Sintorn, Kampe, Olsson, Assarsson
2014)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from OpenGL import GL
from pydantic import Field, field_validator

from harness.config import power_of_two
from harness.technique import AlphaPolicy, Frame, ShadowOutput, Technique, TechniqueParams
from harness.scene.transforms import box_corners

from .casters import quad_casters, triangle_casters
from .hierarchy import SampleHierarchy, closed_sides

# mask_res -> image pixels along each axis per sample (as sv's)
MASK_DIVISOR = {"full": 1, "half": 2, "quarter": 4}
# a point this far behind its own triangle's plane, relative to the scene's largest coordinate,
# counts as shadowed by it: float32 G-buffer positions and planes lie within ~1e-7 of it
TIE = 2.0 ** -20
# how far off the first triangle's plane a quad's fourth corner may lie, relative to the scene's
# largest coordinate: well inside the tie, so the quad's plane decides as both triangles' do
FLATNESS = TIE / 8


class PerTriangleShadowVolumes(Technique):
    """Exact hard shadows without rasterising a volume: each triangle's shadow volume (its
    plane and the three planes through its edges and the light) is tested in a compute shader
    against a hierarchy over the G-buffer's samples, and the samples inside any volume are
    shadowed (Sintorn, Olsson, Assarsson 2011, "An efficient alias-free shadow algorithm for
    opaque and transparent objects using per-triangle shadow volumes"; ``hierarchy: clusters``
    after Sintorn, Kampe, Olsson, Assarsson 2014, "Per-triangle shadow volumes using a
    view-sample cluster hierarchy").

    Every frame, inside timed passes: ``hierarchy`` builds, bottom up, the bounds of each
    ``tile`` x ``tile`` block of samples, then of each such block of blocks, up to one root
    (``hierarchy: tiles``: world-space boxes per screen tile, the 3D bounds of Sintorn's tiles;
    ``hierarchy: clusters``: each tile's samples split by view depth into ``slices`` slices, on a
    log scale over the view depths the scene's bounds span, a box per tile and slice: a cluster
    at the lowest level, and above it each slice's boxes merged per parent tile, as tiles do,
    up to one root over the top level's slices; a tile's box no longer spans every depth it
    holds, as it does where foliage's leaves scatter in depth. Unlike Sintorn 2014 the samples
    are not sorted by their key: a cluster's samples are its tile's samples of its slice);
    ``volumes`` computes every caster's volume from the frame's light (directional, spot or
    point; each caster turned toward the light, an edge-on one casting none, as sv's
    per-triangle volumes; in a closed part only the casters facing the light, which shadow
    all that the part does) and tests the root, then descends level by level: a node outside the
    volume (beyond one of its planes, or beyond its caster's bounds on two axes across the
    light: a directional light's direction, or, after a central projection from a spot or point
    light, its axis) is skipped, one inside is marked shadowed whole, any other
    has its children tested, down to the samples themselves. A volume starts below the top: the
    part of it inside the root's box lies in the hull of its caster and the caster moved along
    the light's rays to where they leave the box, whose projection on the screen and view depth
    range (its footprint) give the lowest level at which at most 2 x 2 nodes cover it, and the
    depth slices; those nodes are tested first and the levels above skipped (a footprint off
    the screen culls the volume; one behind the camera starts at the top). Work moves between levels in
    queues of (volume, node) items filled by atomics (one per item's queued children) and
    dispatched indirectly; an invocation tests one item's node's children in a loop, whatever
    the subgroup size, and only the children that hold a sample (each box carries their bits,
    at level 1 its own samples': the rest of a tile's samples lie in other slices).
    ``visibility`` pushes the marks down to the pixels: V = 0 where a sample or any node above
    it was marked. Samples are tested where they are, so open parts, triangle soups and the
    camera inside a shadow need nothing special, and there is no near or far plane to clip
    against. A point exactly on its own triangle's plane (within float32
    rounding, 2^-20 of the scene's largest coordinate) is not shadowed by it. A sample whose
    visible side (its normal turned toward the camera) faces away from the light receives no
    light whatever shadows it: ``hierarchy`` marks it shadowed (V = 0) and leaves it out of
    the boxes, as rt casts no ray there (such pixels are never compared).

    A caster is a triangle, or with ``quads`` (the default) two triangles that make a planar
    convex quad (each one's longest side the other's, consistently wound, the fourth corner
    within 2^-23 of the scene's largest coordinate of the first one's plane: ``casters.py``):
    the quad's volume (its plane and the planes through its four sides and the light) is the
    union of the two triangles' volumes, so V is the same, and one volume is tested where the
    paper tests two. Grids and cards are such quads, so the volumes, and the traversal's work,
    about halve; ``quads: false`` is the paper's one volume per triangle.

    Counted in an untimed repeat whenever the light, the camera or an object moved:
    ``traversal_nodes`` (node-volume tests, the root's included), ``trivial_accepts`` (nodes
    marked whole; ``root_accepts`` of them at the root), ``triangle_tests`` (sample-volume
    tests: a view sample against one caster's volume; these two are the harness's traversal
    columns, which the cost model prices), ``triangles_culled``
    (edge-on, turned from the light in a closed part, or the root's box outside the volume; a
    quad's two; or its footprint off the screen), ``volumes_queued`` (the casters' volumes
    that were not), ``volumes_seeded`` (of those, the ones starting below the top level),
    ``queue_items``, ``queue_peak`` and ``traversal_batches``. No volume is rasterised
    (``frags_shadow`` 0); ``mem_bytes`` holds the boxes, the marks, the samples' slices
    (clusters), the queued volumes and the work queues, which grow when a frame overflows them,
    up to 2^22 items a queue; past that the casters are traversed in batches
    (``hierarchy.py``).

    ==============  ====================================================  =======  ===========
    Parameter       Meaning                                               Default  Range
    ==============  ====================================================  =======  ===========
    ``hierarchy``   ``clusters``: bounds per screen tile and depth        clusters
                    slice; ``tiles``: per screen tile (cheaper to
                    build; slower where depth varies within a tile)
    ``tile``        children per node along each axis (a power of two:    4        2 .. 4
                    a node's children are bits of one 32-bit word)
    ``slices``      depth slices per tile (clusters only; log depth)      32       2 .. 64
    ``mask_res``    ``full``, ``half`` or ``quarter`` (the samples: one   full
                    pixel per 1, 2 or 4 along each axis; bilinear
                    magnification, as sv)
    ``quads``       two triangles making a planar convex quad cast one    true
                    volume (V the same); ``false``: one per triangle
    ``alpha``       on a scene with alpha-tested casters: ``decline``     decline
                    (skipped: a volume is a whole triangle's) or
                    ``ignore`` (run, cut-outs opaque)
    ==============  ====================================================  =======  ===========
    """

    name = "ptsv"
    colour = "#e377c2"
    summary = "per-triangle shadow volumes tested in compute against a hierarchy of view samples"
    paper = ("Sintorn, Olsson, Assarsson 2011, An efficient alias-free shadow algorithm for "
             "opaque and transparent objects using per-triangle shadow volumes")
    # quality knob: the samples' resolution (error for time), its two ends, to keep make bench
    # within its 10 minutes. The tile and the slices change the cost only, never V (their
    # defaults, tile 4 and 32 slices, measured against tile 2 and 16: docs/techniques.md).
    quality_knobs = {"mask_res": ("quarter", "full")}
    declines_lights = {}  # a volume is the same four planes for every light type
    rivals = ("sv", "rt")  # the other exact methods: volumes with fill, rays

    class Params(TechniqueParams):
        hierarchy: Literal["tiles", "clusters"] = "clusters"
        tile: int = Field(4, ge=2, le=4)
        slices: int = Field(32, ge=2, le=64)
        mask_res: Literal["full", "half", "quarter"] = "full"
        quads: bool = True
        alpha: AlphaPolicy = "decline"

        _tile = field_validator("tile")(power_of_two)

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.divisor = MASK_DIVISOR[p.mask_res]
        scene = frame.scene
        sides = closed_sides(scene.triangles, [len(part.faces) for part in scene.parts],
                             scene.edges.closed)
        vertices, faces = scene.indexed
        casters, caster_sides = (
            quad_casters(vertices, faces, sides, FLATNESS * float(np.abs(scene.bounds).max()))
            if p.quads else (triangle_casters(faces), sides))
        self.hierarchy = SampleHierarchy(frame.width, frame.height, self.divisor, p.tile, casters,
                                         caster_sides,
                                         p.slices if p.hierarchy == "clusters" else 1,
                                         positional=scene.light.positional)
        self.visibility_program = self.shader(__file__, "fullscreen.vert.glsl",
                                              "ptsv_visibility.frag.glsl", TILE=p.tile,
                                              **({"MAGNIFY": 1} if self.divisor > 1 else {}))
        self.counted_for = None
        self.work: dict = {}

    def _tie(self, frame: Frame) -> float:
        bounds = np.abs(frame.scene.bounds).max()
        return TIE * float(max(bounds, np.abs(frame.camera.position).max(), 1e-30))

    @staticmethod
    def _origin(frame: Frame) -> np.ndarray:
        """The centre of the scene's bounds, in float32: positions are taken relative to it."""
        return frame.scene.bounds.mean(axis=0).astype(np.float32)

    @staticmethod
    def _depths(frame: Frame) -> tuple[np.ndarray, tuple[float, float]]:
        """View depth as a plane over positions relative to ``_origin``, and the range of view
        depths the scene's bounds span within the camera's near and far (the clusters' slices
        cut it)."""
        view, camera = frame.camera.view, frame.scene.config.camera
        origin = PerTriangleShadowVolumes._origin(frame).astype(np.float64)
        plane = np.append(-view[2, :3], -(view[2, :3] @ origin + view[2, 3]))
        depths = box_corners(frame.scene.bounds) @ -view[2, :3] - view[2, 3]
        near = min(max(depths.min(), camera.near), camera.far)
        return plane, (near, max(min(depths.max(), camera.far), near))

    def _light(self, frame: Frame) -> np.ndarray:
        light = frame.scene.light
        return (np.append(-light.direction, 0.0) if light.type == "directional"
                else np.append(light.position, 1.0))

    @staticmethod
    def _axis(frame: Frame) -> np.ndarray:
        """A direction the light's rays take: a directional or spot light's own, a point
        light's toward the centre of the scene's bounds (the volumes' cross-section bounds are
        taken across it)."""
        light = frame.scene.light
        if light.type != "point":
            return np.asarray(light.direction, np.float64)
        toward = frame.scene.bounds.mean(axis=0) - np.asarray(light.position, np.float64)
        return toward if np.linalg.norm(toward) > 0 else np.array([0.0, 0.0, -1.0])

    def _build(self, frame: Frame) -> None:
        self.hierarchy.build(frame.gbuffer.position_texture, frame.gbuffer.normal_texture,
                             self._origin(frame), *self._depths(frame),
                             frame.camera.position, self._light(frame))

    def _traverse(self, frame: Frame, count: bool = False) -> np.ndarray:
        mesh = frame.geometry
        return self.hierarchy.traverse(frame.gbuffer.position_texture, mesh.vbo,
                                       self._light(frame), self._axis(frame),
                                       self._origin(frame), self._tie(frame),
                                       frame.camera.view_proj, count)

    def render(self, frame: Frame) -> ShadowOutput:
        h = self.hierarchy
        with frame.measure("hierarchy"):
            self._build(frame)
        with frame.measure("volumes"):
            self._traverse(frame)
        with frame.measure("visibility"):
            frame.begin_visibility()
            program = self.visibility_program.use()
            frame.bind_gbuffer(program)
            program.set(levels=h.levels)
            GL.glUniform2ui(program.location("mask_size"), *h.sizes[0])
            GL.glUniform1ui(program.location("slices"), h.slices)
            h.bind_marks(program)
            frame.draw_fullscreen(covered_only=True)
        self._count(frame)
        taps = 1 if self.divisor == 1 else 4
        return frame.output(mem_bytes=h.mem_bytes, fetches_per_px=taps * (h.levels + 1),
                            shadow_fragments=0, extra=dict(self.work))

    def _count(self, frame: Frame) -> None:
        """The untimed repeat: the traversal again, counting its work, when the light, the
        camera or an object moved (once on a still scene); V is not changed by it."""
        light = frame.scene.light
        key = (self._light(frame).tobytes(), frame.camera.view_proj.tobytes(),
               frame.part_poses.tobytes(), light.type)
        if key == self.counted_for:
            return
        self.counted_for = key
        self._build(frame)  # the marks cleared (and the unreached samples marked) again
        self.work = self.hierarchy.counts(self._traverse(frame, count=True))

    def release(self) -> None:
        self.hierarchy.release()
        self.visibility_program.release()
