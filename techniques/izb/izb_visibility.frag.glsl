// V = the fraction of the pixel's samples whose mask bit stayed clear (lit).
layout(std430, binding = 2) readonly buffer Masks { uint masks[]; };
uniform int width;
out vec4 visibility;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    uint mask = masks[pixel.y * width + pixel.x];
    visibility = vec4(1.0 - float(bitCount(mask)) / float(SAMPLES));
}
