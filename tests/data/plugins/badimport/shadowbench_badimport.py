"""A plugin that needs a package that is not installed."""

import shadowbench_no_such_dependency  # noqa: F401
