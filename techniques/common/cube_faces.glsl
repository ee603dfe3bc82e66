// A point light's map (shadow_map.glsl with CUBE_FACES): six perspective faces, the layers of
// one array, each a linear-depth map along its own axis (harness.scene.transforms.cube_faces). A
// shaded point takes the face its direction from the light falls in, by the largest
// component; that face's view then stands for light_view in every lookup and bias of the
// point, so the bias rule is the one of a single map, per face texel. For pcf the faces are
// wider than 90 degrees by a guard band (map_res is then the whole face): a percentage-closer
// sample past the face's own edge still reads real depths of that face instead of falling off.
uniform sampler2DArray shadow_map;
uniform mat4 face_views[6];
uniform mat4 light_proj;  // the faces share it
uniform float map_res;
uniform vec3 light_position;
mat4 light_view;
int face_layer;

void choose_face(vec3 world) {
    vec3 d = world - light_position;
    vec3 a = abs(d);
    int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    face_layer = 2 * axis + (d[axis] < 0.0 ? 1 : 0);
    light_view = face_views[face_layer];
}

float map_depth(ivec2 cell) {
    return texelFetch(shadow_map, ivec3(cell, face_layer), 0).r;
}
