// The view-dependence bound of reprojection (docs/PIPELINE.md, "The view-dependence bound";
// twin: parallax_passes::view_bound, whose tests check it against the material model): an
// upper bound of the relative change of the BSDF value f(wi, wo) cos(wi), for any incident
// direction wi, when wo turns by an angle theta away from the view direction `v`. Radiance
// reflected towards wo is the integral of f cos times the incident light, so the same bound
// holds for the radiance under any lighting: the error of reusing a source's radiance seen
// theta away. It grows with theta, with the narrowness of the GGX lobe (alpha = roughness^2),
// the Fresnel and visibility terms, and with the share of the specular lobe in f.

#ifndef VIEW_BOUND_GLSL
#define VIEW_BOUND_GLSL

#include "pt_constants.glsl"

// Least Fresnel F0 the bound assumes: below it (black metal, not a physical material) the
// relative change of Schlick's Fresnel has no bound.
const float VIEW_BOUND_MIN_F0 = 0.02;

// What the bound needs of one surface and view: error(theta) = max over rgb of
// lobe_share (e^(lobe_rate theta) - 1) + peak_share (e^(peak_rate theta) - 1), plus
// e^(diffuse_rate theta) - 1.
struct ViewBound {
    vec3 lobe_share;    // specular share where the GGX lobe is steepest
    vec3 peak_share;    // specular share at the lobe's peak
    float lobe_rate;    // |d ln D / d theta|: the lobe's slope, per radian of view change
    vec3 peak_rate;     // Fresnel and visibility terms of the specular lobe, per radian
    float diffuse_rate; // the diffuse lobe's Fresnel weight, per radian (0 for metals)
};

// (1 - c)^5: Schlick's weight.
float view_bound_schlick(float c) {
    float x = clamp(1.0 - c, 0.0, 1.0);
    float x2 = x * x;
    return x2 * x2 * x;
}

// The bound's terms at a surface of shading normal `n`, seen along `v` (unit, towards the
// eye), of base colour `base`, `metallic` and perceptual `roughness` (glTF). The dielectric
// specular factor is taken as 1 (the G-buffer does not hold it; 1 is its most specular value).
ViewBound view_bound_of(vec3 n, vec3 v, vec3 base, float metallic, float roughness) {
    ViewBound b;
    float alpha = max(roughness * roughness, MIN_ALPHA);
    float a2 = alpha * alpha;
    float c = clamp(dot(n, v), 1e-4, 1.0);
    // The least cos(v, h) over every wi of the hemisphere: wi at grazing, opposite v.
    float c_min = 0.5 * (sqrt(1.0 + c) - sqrt(1.0 - c));
    float fw = view_bound_schlick(c);
    vec3 f0 = max(mix(vec3(0.04), base, metallic), vec3(VIEW_BOUND_MIN_F0));
    vec3 f_v = f0 + (1.0 - f0) * fw;
    vec3 diffuse = (1.0 - metallic) * base * (0.96 - 0.96 * fw);
    b.lobe_share = f_v / (f_v + 7.7 * a2 * c * c * diffuse);
    b.peak_share = f_v / (f_v + 4.0 * a2 * c * c * diffuse);
    b.lobe_rate = (1.0 - a2) / (alpha * c_min);
    // max over cos(v, h) of |d ln F / d theta_d| (Schlick), attained where
    // (1 - cos)^5 = 4 F0 / (1 - F0), or at grazing once F0 >= 0.2.
    vec3 x = min(pow(4.0 * f0 / max(1.0 - f0, vec3(1e-6)), vec3(0.2)), vec3(1.0));
    vec3 x4 = (x * x) * (x * x);
    vec3 fresnel = mix((1.0 - f0) * x4 / f0, 5.0 * (1.0 - f0), greaterThanEqual(x, vec3(1.0)));
    float tan_v = sqrt(max(1.0 - c * c, 0.0)) / c;
    b.peak_rate = 0.5 * fresnel + tan_v + alpha;
    float cd = view_bound_schlick(c_min);
    float diffuse_slope = 5.0 * (cd / (1.0 - c_min)) * sqrt(max(1.0 - c_min * c_min, 0.0)) / (1.0 - cd);
    b.diffuse_rate = metallic < 1.0 ? 0.5 * diffuse_slope : 0.0;
    return b;
}

// The angle between two unit vectors, accurate for small angles (where acos is not).
float view_angle(vec3 a, vec3 b) {
    return 2.0 * asin(min(0.5 * length(a - b), 1.0));
}

// The bound of the relative radiance error for a view change of `theta` radians.
float view_bound_error(ViewBound b, float theta) {
    vec3 e = b.lobe_share * (exp(b.lobe_rate * theta) - 1.0) + b.peak_share * (exp(b.peak_rate * theta) - 1.0);
    return max(max(e.r, e.g), e.b) + (exp(b.diffuse_rate * theta) - 1.0);
}

#endif
