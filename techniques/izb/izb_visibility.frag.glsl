// V = the fraction of the pixel's samples whose mask bit stayed clear (lit); with
// RASTER_SURFACE, of those whose ray met a surface (as the reference counts its samples).
layout(std430, binding = 2) readonly buffer Masks { uint masks[]; };
#ifdef RASTER_SURFACE
layout(std430, binding = 6) readonly buffer Missed { uint missed[]; };
#endif
uniform int width;
out vec4 visibility;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    uint index = uint(pixel.y * width + pixel.x);
    uint shadowed = masks[index];
    float hits = float(SAMPLES);
#ifdef RASTER_SURFACE
    hits -= float(bitCount(missed[index]));
#endif
    visibility = vec4(hits > 0.0 ? 1.0 - float(bitCount(shadowed)) / hits : 1.0);
}
