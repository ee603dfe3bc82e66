// One receiver's reads under bias_mode adaptive, as shadow_map.glsl computes them
// (tests/techniques/test_adaptive_bias.py): pixel x of the row reads the texel centre
// first_centre + x * step. Out: the tangent plane's depth there less the point's
// (plane_offset), the read's bias (receiver_bias), the point's light depth and |g|.
#include "../../techniques/common/shadow_map.glsl"

uniform vec3 point;
uniform vec3 point_normal;
uniform vec2 first_centre;
uniform vec2 step;
layout(location = 0) out vec4 result;

void main() {
    Receiver r = receiver(point, point_normal);
    vec2 centre = first_centre + floor(gl_FragCoord.x) * step;
    result = vec4(plane_offset(r, centre), receiver_bias(r, centre, vec2(0.0), vec2(0.0)),
                  r.depth, length(r.depth_slope));
}
