#version 330 core
// glref vertex stage: model space -> clip space, pass the vertex attributes on.
// Specialised by #define (inserted by glref after the #version line):
//   HAS_COLOR   the mesh has per-vertex RGBA colours (else white)
//   HAS_TEXTURE the material samples a texture: pass the uvs on

uniform mat4 u_mvp;          // P @ V @ world, computed in float64 on the CPU

in vec3 in_position;         // model space
#ifdef HAS_COLOR
in vec4 in_color;            // straight (not premultiplied) RGBA
out vec4 v_color;            // perspective-correct (smooth) by default
#endif
#ifdef HAS_TEXTURE
in vec2 in_uv;               // (s, t); t = 0 is the first (top) row of the image
out vec2 v_uv;
#endif

void main() {
    gl_Position = u_mvp * vec4(in_position, 1.0);
#ifdef HAS_COLOR
    v_color = in_color;
#endif
#ifdef HAS_TEXTURE
    v_uv = in_uv;
#endif
}
