"""The one build step pyproject.toml cannot say: the scenes and experiments at the repository's
root (scenes.yaml, experiments/ with the meshes and scene files its experiments name) go into
the wheel as package data, harness/shipped/, where harness.config.shipped finds them when an
installed shadowbench runs from another folder. An editable install reads them in place."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
SHIPPED = ("scenes.yaml", "experiments")  # what harness/config/shipped.py looks for


class BuildWithShipped(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        target = Path(self.build_lib) / "harness" / "shipped"
        for name in SHIPPED:
            source, copy = ROOT / name, target / name
            if source.is_dir():
                shutil.copytree(source, copy, dirs_exist_ok=True,
                                ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
            else:
                copy.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, copy)


setup(cmdclass={"build_py": BuildWithShipped})
