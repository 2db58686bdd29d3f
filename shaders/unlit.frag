#version 330 core
// glref fragment stage: colour = vertex colour x material colour, written
// PREMULTIPLIED (rgb * a, a) as docs/design.md section 4 requires, times the texel
// (the texture holds premultiplied texels).
// Specialised by #define (inserted by glref after the #version line):
//   HAS_COLOR   a per-vertex colour arrives from the vertex stage
//   HAS_TEXTURE sample u_texture at v_uv (implicit derivatives, GL's LOD)
//   ALPHA_TEST  discard fragments whose final alpha is below u_alpha_cutoff

uniform vec4 u_color;        // material colour, straight RGBA

#ifdef HAS_COLOR
in vec4 v_color;
#endif
#ifdef HAS_TEXTURE
uniform sampler2D u_texture; // premultiplied RGBA8, every mip level uploaded by glref
in vec2 v_uv;
#endif

#ifdef ALPHA_TEST
uniform float u_alpha_cutoff; // material alpha_cutoff: fragments with alpha below it are discarded
#endif

out vec4 f_color;

void main() {
#ifdef HAS_COLOR
    vec4 c = v_color * u_color;
#else
    vec4 c = u_color;
#endif
    f_color = vec4(c.rgb * c.a, c.a);
#ifdef HAS_TEXTURE
    f_color *= texture(u_texture, v_uv);
#endif
#ifdef ALPHA_TEST
    // glTF MASK: alpha >= cutoff is opaque, below it the fragment is dropped
    // (once per fragment, also with MSAA: every covered sample goes).
    if (f_color.a < u_alpha_cutoff) discard;
#endif
}
