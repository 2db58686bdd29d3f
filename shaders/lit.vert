#version 330 core
// glref vertex stage for lit materials (Blinn-Phong, see lighting.glsl).
// Specialised by #define (inserted by glref after the #version line):
//   HAS_COLOR        per-vertex RGBA colours (else white)
//   HAS_TEXTURE      pass the uvs on
//   SHADING_FLAT     pass world positions on; the geometry stage lights each face
//   SHADING_GOURAUD  light each vertex here; the colour is interpolated
//   SHADING_PHONG    pass world position and normal on; light each fragment
//   NUM_LIGHTS n     number of lights (>= 1)
//   NORMAL_MAP / BUMP_MAP  (with SHADING_PHONG) pass the world tangent and the uvs on

uniform mat4 u_mvp;          // P @ V @ world (float64 on the CPU)
uniform mat4 u_world;        // model -> world
uniform mat3 u_normal_matrix; // inverse-transpose of world's 3x3 (float64 on the CPU)
uniform vec4 u_color;        // material colour, straight RGBA

in vec3 in_position;
#ifdef HAS_COLOR
in vec4 in_color;
#endif
#ifndef SHADING_FLAT
in vec3 in_normal;           // model space
#endif
#if defined(HAS_TEXTURE) || defined(NORMAL_MAP) || defined(BUMP_MAP)
#define HAS_UV 1
#endif
#ifdef HAS_UV
in vec2 in_uv;
out vec2 v_uv;
#endif
#if defined(NORMAL_MAP) || defined(BUMP_MAP)
uniform float u_handedness;  // sign(det) of world's 3x3 (a mirror flips the bitangent)
in vec4 in_tangent;          // model space: unit tangent (xyz), handedness w (softras.meshes.vertex_tangents)
out vec4 v_tangent;          // world tangent (unnormalised), handedness
#endif

#ifdef SHADING_GOURAUD
out vec4 v_color;            // lit, straight RGBA
#else
out vec4 v_base;             // vertex colour x material colour, straight RGBA
out vec3 v_world;            // world position
#endif
#ifdef SHADING_PHONG
out vec3 v_normal;           // world normal (unnormalised after interpolation)
#endif

void main() {
    gl_Position = u_mvp * vec4(in_position, 1.0);
#ifdef HAS_COLOR
    vec4 base = in_color * u_color;
#else
    vec4 base = u_color;
#endif
    vec3 world = (u_world * vec4(in_position, 1.0)).xyz;
#ifdef SHADING_GOURAUD
    vec3 n = normalize(u_normal_matrix * in_normal);
    v_color = vec4(blinn_phong(base.rgb, world, n), base.a);
#else
    v_base = base;
    v_world = world;
#endif
#ifdef SHADING_PHONG
    v_normal = u_normal_matrix * in_normal;
#endif
#ifdef HAS_UV
    v_uv = in_uv;
#endif
#if defined(NORMAL_MAP) || defined(BUMP_MAP)
    v_tangent = vec4(mat3(u_world) * in_tangent.xyz, in_tangent.w * u_handedness);
#endif
}
