// Blinn-Phong lighting shared by the lit shader stages (glref pastes this text
// after the #defines).  Everything in WORLD space.
//
//   base   straight RGB of vertex colour x material colour
//   P      world position, N unit world normal
//   colour = ambient * base
//          + sum over lights with N.L > 0 of
//              light_colour * (diffuse * (N.L) * base + specular * max(N.H, 0)^shininess)
//   L = normalize(light position - P) (point) or normalize(-direction) (directional),
//   V = normalize(eye - P), H = normalize(L + V).  No attenuation, no clamping
//   (the framebuffer clamps).
//
// u_light[i] = (position, 1) for a point light, (-direction, 0) for a directional one.

uniform vec3 u_eye;                      // camera position, world space
uniform vec4 u_light[NUM_LIGHTS];
uniform vec3 u_light_color[NUM_LIGHTS];
uniform float u_ambient;
uniform float u_diffuse;
uniform float u_specular;
uniform float u_shininess;

vec3 blinn_phong(vec3 base, vec3 P, vec3 N) {
    vec3 V = normalize(u_eye - P);
    vec3 c = u_ambient * base;
    for (int i = 0; i < NUM_LIGHTS; ++i) {
        vec3 L = normalize(u_light[i].xyz - P * u_light[i].w);
        float n_dot_l = dot(N, L);
        if (n_dot_l > 0.0) {
            vec3 H = normalize(L + V);
            float spec = pow(max(dot(N, H), 0.0), u_shininess);
            c += u_light_color[i] * (u_diffuse * n_dot_l * base + u_specular * spec);
        }
    }
    return c;
}
