"""The built-in techniques, one package per technique or family.

Each package holds its Python and its shaders and registers its class through the
``shadowbench.techniques`` entry point (pyproject.toml), as a third-party plugin would. Packages
import ``harness`` and ``techniques.common``, never each other (import-linter checks it). Start
with ``sm/sm.py``, a whole technique in one page; the contract is ``harness/technique/__init__.py``.
"""
