// The camera G-buffer: world position (w = 1 where covered) and flat normal (w = albedo; not
// defined where not covered).
uniform sampler2D gbuffer_position;
uniform sampler2D gbuffer_normal;

bool gbuffer_fetch(out vec3 position, out vec3 normal) {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    position = p.xyz;
    normal = texelFetch(gbuffer_normal, pixel, 0).xyz;
    return p.w > 0.5;
}
