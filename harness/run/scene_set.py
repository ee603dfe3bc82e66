"""The plan's scenes, each built when a run asks for it and the large ones let go after their
group (harness.run.plan's Plan holds one): at most one 10^6-triangle scene is resident."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .. import config as cfg
from ..scene import BuiltScene, build_scene

# Triangles from which a built scene is kept only while it is the last one asked for.
LARGE_SCENE = 2**18


class SceneSet(Mapping):
    """The plan's scenes by name (in the plan's order), each built when asked for: one under
    LARGE_SCENE triangles is kept once built, a larger one only until another scene is asked
    for or :meth:`release` (the sweep's, after that scene's group), so no two 10^6-triangle
    scenes are ever built at once. Before, the plan held every scene built for the whole run
    (make scale: the four families at 10^3 to 10^6, 0.1 GiB). A scene asked for again after
    another large one is built again (a few seconds at 10^6): the sweep asks once per group.
    :meth:`described` reads what no scene needs building for."""

    def __init__(self, configs: dict[str, cfg.Scene], source: Path | None):
        self.configs = dict(configs)
        self.source = source
        self._small: dict[str, BuiltScene] = {}
        self._large: tuple[str, BuiltScene] | None = None

    def __getitem__(self, name: str) -> BuiltScene:
        if name in self._small:
            return self._small[name]
        if self._large is not None and self._large[0] == name:
            return self._large[1]
        config = self.configs[name]  # KeyError for a scene the plan does not have
        self._large = None  # let the last large scene go before building the next
        scene = build_scene(name, config, self.source)
        if sum(len(part.faces) for part in scene.parts) < LARGE_SCENE:
            self._small[name] = scene
        else:
            self._large = (name, scene)
        return scene

    def __iter__(self):
        return iter(self.configs)

    def __len__(self) -> int:
        return len(self.configs)

    def release(self) -> None:
        """Let the large scene kept go (the small ones stay)."""
        self._large = None

    def described(self) -> list[tuple[str, cfg.Scene, Path | None]]:
        """Each scene's name, description and the file its paths are relative to."""
        return [(name, config, self.source) for name, config in self.configs.items()]
