// The material model, the twin of parallax_scene::bsdf: glTF metallic-roughness as Lambert +
// GGX (Smith height-correlated, Schlick Fresnel), GGX VNDF sampling (Heitz 2018), one-sample
// lobe choice. Directions point away from the surface.

#ifndef PT_BSDF_GLSL
#define PT_BSDF_GLSL

#include "pt_constants.glsl"
#include "pt_surface.glsl"

struct Bsdf {
    vec3 n;
    vec3 ng;
    vec3 base;
    float metallic;
    float specular;
    float alpha;
    float p_specular;
};

// Duff et al. 2017; Rust's copysign keeps the sign of -0.0.
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float s = (floatBitsToUint(n.z) & 0x80000000u) != 0u ? -1.0 : 1.0;
    float a = -1.0 / (s + n.z);
    float bb = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * bb, -s * n.x);
    b = vec3(bb, s + n.y * n.y * a, -n.y);
}

vec3 sample_cosine_hemisphere(vec3 n, float u0, float u1) {
    float r = sqrt(u0);
    float phi = TAU * u1;
    vec3 t, b;
    orthonormal_basis(n, t, b);
    return normalize(t * (r * cos(phi)) + b * (r * sin(phi)) + n * sqrt(max(1.0 - u0, 0.0)));
}

float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

float schlick_weight(float c) {
    float x = clamp(1.0 - c, 0.0, 1.0);
    float x2 = x * x;
    return x2 * x2 * x;
}

Bsdf bsdf_new(SurfacePoint sp, vec3 wo) {
    Bsdf f;
    f.n = sp.normal;
    f.ng = sp.geometric_normal;
    f.base = sp.base_color;
    f.metallic = sp.metallic;
    f.specular = sp.specular;
    f.alpha = max(sp.roughness * sp.roughness, MIN_ALPHA);
    float fw = schlick_weight(max(dot(sp.normal, wo), 1e-4));
    float f_dielectric = sp.specular * (0.04 + 0.96 * fw);
    vec3 f_metal = sp.base_color + (1.0 - sp.base_color) * fw;
    float spec = luminance(mix(vec3(f_dielectric), f_metal, sp.metallic));
    float diff = luminance(sp.base_color) * (1.0 - sp.metallic) * (1.0 - f_dielectric);
    if (spec <= 0.0) {
        f.p_specular = 0.0;
    } else if (diff <= 0.0) {
        f.p_specular = 1.0;
    } else {
        f.p_specular = clamp(spec / (spec + diff), 0.1, 0.9);
    }
    return f;
}

float bsdf_d_ggx(Bsdf f, float n_dot_h) {
    float a2 = f.alpha * f.alpha;
    float d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

float bsdf_lambda(Bsdf f, float c) {
    float c2 = c * c;
    float tan2 = max(1.0 - c2, 0.0) / max(c2, 1e-12);
    return 0.5 * (-1.0 + sqrt(1.0 + f.alpha * f.alpha * tan2));
}

// f * cos(wi) in rgb, pdf(wi) in w.
vec4 bsdf_eval(Bsdf f, vec3 wo, vec3 wi) {
    if (!(dot(f.n, wo) > 0.0 && dot(f.n, wi) > 0.0 && dot(f.ng, wi) > 0.0 && dot(f.ng, wo) > 0.0)) {
        return vec4(0.0);
    }
    float n_dot_v = max(dot(f.n, wo), 1e-6);
    float n_dot_l = max(dot(f.n, wi), 1e-6);
    vec3 hv = wo + wi;
    float hl = length(hv);
    if (hl == 0.0) {
        return vec4(0.0);
    }
    vec3 h = hv / hl;
    float n_dot_h = max(dot(f.n, h), 0.0);
    float v_dot_h = clamp(dot(wo, h), 0.0, 1.0);
    float fw = schlick_weight(v_dot_h);
    float f_dielectric = f.specular * (0.04 + 0.96 * fw);
    vec3 f_metal = f.base + (1.0 - f.base) * fw;
    vec3 fr = mix(vec3(f_dielectric), f_metal, f.metallic);
    float d = bsdf_d_ggx(f, n_dot_h);
    float lambda_v = bsdf_lambda(f, n_dot_v);
    float g2 = 1.0 / (1.0 + lambda_v + bsdf_lambda(f, n_dot_l));
    vec3 specular = fr * (d * g2 / (4.0 * n_dot_v * n_dot_l));
    vec3 diffuse = f.base * ((1.0 - f.metallic) * (1.0 - f_dielectric) * INV_PI);
    float pdf_spec = d / (1.0 + lambda_v) / (4.0 * n_dot_v);
    float pdf_diff = n_dot_l * INV_PI;
    float pdf = f.p_specular * pdf_spec + (1.0 - f.p_specular) * pdf_diff;
    return vec4((diffuse + specular) * n_dot_l, pdf);
}

vec3 sample_ggx_vndf(vec3 v, float alpha, float u0, float u1) {
    vec3 vh = normalize(vec3(alpha * v.x, alpha * v.y, v.z));
    float len_sq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = len_sq > 0.0 ? vec3(-vh.y, vh.x, 0.0) / sqrt(len_sq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u0);
    float phi = TAU * u1;
    float p1 = r * cos(phi);
    float s = 0.5 * (1.0 + vh.z);
    float p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    vec3 nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(nh.z, 0.0)));
}

// Samples a direction; returns false if none. weight = f * cos / pdf.
bool bsdf_sample(Bsdf f, vec3 wo, vec3 u, out vec3 wi, out vec3 weight, out float pdf) {
    wi = vec3(0.0);
    weight = vec3(0.0);
    pdf = 0.0;
    if (dot(f.n, wo) <= 0.0) {
        return false;
    }
    if (u.x < f.p_specular) {
        vec3 t, b;
        orthonormal_basis(f.n, t, b);
        vec3 m = sample_ggx_vndf(vec3(dot(wo, t), dot(wo, b), dot(wo, f.n)), f.alpha, u.y, u.z);
        vec3 mw = t * m.x + b * m.y + f.n * m.z;
        vec3 r = 2.0 * dot(wo, mw) * mw - wo;
        float rl = length(r);
        wi = rl > 0.0 ? r / rl : vec3(0.0);
    } else {
        wi = sample_cosine_hemisphere(f.n, u.y, u.z);
    }
    vec4 e = bsdf_eval(f, wo, wi);
    if (!(e.w > 0.0) || isinf(e.w)) {
        return false;
    }
    pdf = e.w;
    weight = e.rgb / e.w;
    return !any(isnan(weight)) && !any(isinf(weight));
}

#endif
