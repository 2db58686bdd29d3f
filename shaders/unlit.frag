#version 330 core
// glref fragment stage: colour = vertex colour x material colour, written
// PREMULTIPLIED (rgb * a, a) as docs/design.md section 4 requires, times the texel
// (the texture holds premultiplied texels).
// Specialised by #define (inserted by glref after the #version line):
//   HAS_COLOR   a per-vertex colour arrives from the vertex stage
//   HAS_TEXTURE sample u_texture at v_uv (implicit derivatives, GL's LOD)

uniform vec4 u_color;        // material colour, straight RGBA

#ifdef HAS_COLOR
in vec4 v_color;
#endif
#ifdef HAS_TEXTURE
uniform sampler2D u_texture; // premultiplied RGBA8, every mip level uploaded by glref
in vec2 v_uv;
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
}
