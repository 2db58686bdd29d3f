#version 330 core
// glref geometry stage for flat shading: one Blinn-Phong colour per triangle,
// lit with the face normal normalize(cross(p1 - p0, p2 - p0)) (world space,
// counter-clockwise = front) at the face centroid (p0 + p1 + p2) / 3, with
// the base colour of the provoking (last) vertex, as GL's flat qualifier.

layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;

in vec4 v_base[];
in vec3 v_world[];
#ifdef HAS_TEXTURE
in vec2 v_uv[];
out vec2 g_uv;
#endif
flat out vec4 g_color;

void main() {
    vec3 p0 = v_world[0], p1 = v_world[1], p2 = v_world[2];
    vec3 n = normalize(cross(p1 - p0, p2 - p0));
    vec3 middle = (p0 + p1 + p2) / 3.0;
    vec4 base = v_base[2];
    vec4 c = vec4(blinn_phong(base.rgb, middle, n), base.a);
    for (int k = 0; k < 3; ++k) {
        gl_Position = gl_in[k].gl_Position;
        g_color = c;
#ifdef HAS_TEXTURE
        g_uv = v_uv[k];
#endif
        EmitVertex();
    }
    EndPrimitive();
}
