"""sm with a larger default bias: a subclass of sm's class, as a user's first plugin is."""

from pydantic import Field

from techniques.sm import ShadowMap


class BiasedShadowMap(ShadowMap):
    """sm with a larger default depth bias (the rest is sm's).

    =================  ==========================================  =======  ===========
    Parameter          Meaning                                     Default  Range
    =================  ==========================================  =======  ===========
    ``res``            map width and height, texels                1024     16 .. 8192
    ``bias``           constant depth bias, scene units            0.05     >= 0
    ``slope_bias``     times the receiver plane's depth slope      1.0      >= 0
    ``bias_mode``      slope, receiver_plane or adaptive           slope
    ``normal_offset``  along the normal, times the texel's size    0.0      >= 0
    =================  ==========================================  =======  ===========
    """

    name = "smbias"
    summary = "sm with a larger default bias"

    class Params(ShadowMap.Params):
        bias: float = Field(0.05, ge=0)
