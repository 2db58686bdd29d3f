#version 450 core
// glref fragment stage for lit materials: the lit colour (per face, vertex or
// fragment, see lit.vert) premultiplied, times the premultiplied texel.

#ifdef HAS_TEXTURE
uniform sampler2D u_texture;
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

out vec4 f_color;

void main() {
#if defined(SHADING_FLAT)
    vec4 c = g_color;
#elif defined(SHADING_GOURAUD)
    vec4 c = v_color;
#else
    vec4 c = vec4(blinn_phong(v_base.rgb, v_world, normalize(v_normal)), v_base.a);
#endif
    f_color = vec4(c.rgb * c.a, c.a);
#ifdef HAS_TEXTURE
    f_color *= texture(u_texture, UV);
#endif
}
