"""A second baseline: sm's class declaring ``baseline = True`` in its own body."""

from techniques.sm import ShadowMap


class OtherBaseline(ShadowMap):
    """sm, declared the baseline again (the parameters are sm's)."""

    name = "smbase"
    summary = "sm declared the baseline a second time"
    baseline = True
