#version 330 core
// glref fragment stage for lit materials: the lit colour (per face, vertex or
// fragment, see lit.vert) premultiplied, times the premultiplied texel.
// NORMAL_MAP / BUMP_MAP (Phong only): the normal is perturbed per fragment
// (softras.fragment.perturb_normals, normal_map_normals, bump_normals).

#ifdef HAS_TEXTURE
uniform sampler2D u_texture;
#endif
#ifdef NORMAL_MAP
uniform sampler2D u_normal_map;  // tangent-space normals, rgb = (n + 1) / 2
#endif
#ifdef BUMP_MAP
uniform sampler2D u_bump_map;    // height in the red channel
uniform vec2 u_bump_texel;       // (1 / width, 1 / height) of its level 0
uniform float u_bump_scale;
#endif

#ifdef SHADING_FLAT
flat in vec4 g_color;
#ifdef HAS_TEXTURE
in vec2 g_uv;
#define UV g_uv
#endif
#else
#ifdef HAS_TEXTURE
in vec2 v_uv;
#define UV v_uv
#endif
#endif
#ifdef SHADING_GOURAUD
in vec4 v_color;
#endif
#ifdef SHADING_PHONG
in vec4 v_base;
in vec3 v_world;
in vec3 v_normal;
#endif
#if defined(NORMAL_MAP) || defined(BUMP_MAP)
#ifndef HAS_TEXTURE
in vec2 v_uv;
#endif
in vec4 v_tangent;

// World normal from the tangent frame (T, B, N) and a tangent-space normal.
vec3 mapped_normal(vec3 N) {
    vec3 T = normalize(v_tangent.xyz - N * dot(N, v_tangent.xyz));
    vec3 B = (v_tangent.w < 0.0 ? -1.0 : 1.0) * cross(N, T);
#ifdef NORMAL_MAP
    vec3 n = 2.0 * texture(u_normal_map, v_uv).rgb - 1.0;
#else
    // Central differences one level-0 texel either side (implicit LOD).
    float dh_s = texture(u_bump_map, v_uv + vec2(u_bump_texel.x, 0.0)).r
               - texture(u_bump_map, v_uv - vec2(u_bump_texel.x, 0.0)).r;
    float dh_t = texture(u_bump_map, v_uv + vec2(0.0, u_bump_texel.y)).r
               - texture(u_bump_map, v_uv - vec2(0.0, u_bump_texel.y)).r;
    vec3 n = vec3(-u_bump_scale * dh_s * 0.5, -u_bump_scale * dh_t * 0.5, 1.0);
#endif
    return normalize(n.x * T + n.y * B + n.z * N);
}
#endif

#ifdef ALPHA_TEST
uniform float u_alpha_cutoff; // material alpha_cutoff: fragments with alpha below it are discarded
#endif

out vec4 f_color;

void main() {
#if defined(SHADING_FLAT)
    vec4 c = g_color;
#elif defined(SHADING_GOURAUD)
    vec4 c = v_color;
#elif defined(NORMAL_MAP) || defined(BUMP_MAP)
    vec4 c = vec4(blinn_phong(v_base.rgb, v_world, mapped_normal(normalize(v_normal))), v_base.a);
#else
    vec4 c = vec4(blinn_phong(v_base.rgb, v_world, normalize(v_normal)), v_base.a);
#endif
    f_color = vec4(c.rgb * c.a, c.a);
#ifdef HAS_TEXTURE
    f_color *= texture(u_texture, UV);
#endif
#ifdef ALPHA_TEST
    // glTF MASK: alpha >= cutoff is opaque, below it the fragment is dropped
    // (once per fragment, also with MSAA: every covered sample goes).
    if (f_color.a < u_alpha_cutoff) discard;
#endif
}
