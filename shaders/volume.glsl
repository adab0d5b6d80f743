// Glass solids (KHR_materials_volume; core/volume.py has the physics and the bake's side): where
// a transmission sample's light comes from, and what reaches the eye of it. The thin lobe of
// Eq. 3.5 carries the entry interface (its 1 - F); this adds the refraction, the exit
// interface(s) and the Beer-Lambert absorption inside. The object's shape is known here only by
// its bounding box (CubeObject.extent) and the glTF thickness, so:
// - thin-walled (the wall along the refracted ray, thickness / cos_t, under half the chord
//   through the box's inscribed ellipsoid: bottles, glasses, vases): each wall is a slab,
//   leaving the direction unchanged, and the ray crosses two walls of the closed object
//   (front and back): (1 - F)^3 after the lobe's entry, absorption over 2 thickness / cos_t;
// - solid (a paperweight, a thick lens; a pane, whose ellipsoid is as flat as the pane): the
//   ray refracts in (Snell), runs to the far side of the inscribed ellipsoid, and refracts out
//   through the ellipsoid's normal there (1 - F with the exact Fresnel from inside, total
//   internal reflection followed up to VOLUME_BOUNCES times), absorbed over its length inside;
//   the part F reflected there crosses the solid again and leaves where it meets the ellipsoid
//   next (a second look-up).
// The look-ups then start from the exit points (bounding planes, section 4.4.1).

#include "common.glsl"

const int VOLUME_BOUNCES = 3;

struct CubeLook {
    vec3 dir;      // the look-up direction in the object's cube map
    vec3 weight;   // what the glass lets through of the radiance found there
    vec3 dir2;     // a second look-up: the light a thin-walled solid's far wall reflects to the eye
    vec3 weight2;  // its weight; 0: no second look-up
};

CubeLook single_look(vec3 dir, vec3 weight) {
    return CubeLook(dir, weight, dir, vec3(0.0));
}

// CUBE_VOLUMES (viewer/cubemaps.py): 0 where the scene has no glass solid, which leaves this file's
// code out of the programs.
bool has_volume(CubeObject c) {
    return CUBE_VOLUMES != 0 && c.volume.a > 0.0;
}

// Unpolarised Fresnel reflectance from index 1 into index eta at cos_i (core/volume.py
// fresnel_dielectric); 1 under total internal reflection.
float fresnel_dielectric(float cos_i, float eta) {
    float c = clamp(abs(cos_i), 0.0, 1.0);
    float sin2_t = (1.0 - c * c) / (eta * eta);
    if (sin2_t >= 1.0)
        return 1.0;
    float cos_t = sqrt(1.0 - sin2_t);
    float rs = (c - eta * cos_t) / max(c + eta * cos_t, 1e-12);
    float rp = (eta * c - cos_t) / max(eta * c + cos_t, 1e-12);
    return 0.5 * (rs * rs + rp * rp);
}

// The object's oriented box (viewer/cubemaps.py): world -> box coordinates, and its half extents.
vec3 box_local(CubeObject c, vec3 v) {
    return vec3(dot(c.box[0].xyz, v), dot(c.box[1].xyz, v), dot(c.box[2].xyz, v));
}

vec3 box_centre(CubeObject c) {
    return vec3(c.box[0].w, c.box[1].w, c.box[2].w);
}

vec3 box_half(CubeObject c) {
    return max(c.extent.xyz, vec3(1e-4));
}

// The far intersection s > 0 of p + s d with the ellipsoid inscribed in the box, or -1.
float ellipsoid_exit(CubeObject c, vec3 p, vec3 d) {
    vec3 h = box_half(c);
    vec3 o = box_local(c, p - box_centre(c)) / h;
    vec3 v = box_local(c, d) / h;
    float a = dot(v, v), b = dot(o, v), k = dot(o, o) - 1.0;
    float disc = b * b - a * k;
    if (!(disc >= 0.0) || !(a > 0.0))
        return -1.0;
    return (-b + sqrt(disc)) / a;
}

// The inscribed ellipsoid's outward unit normal at its point q (`fallback` where it has none).
vec3 ellipsoid_normal(CubeObject c, vec3 q, vec3 fallback) {
    vec3 h = box_half(c);
    vec3 g = box_local(c, q - box_centre(c)) / (h * h);
    return safe_normalize(g.x * c.box[0].xyz + g.y * c.box[1].xyz + g.z * c.box[2].xyz, fallback);
}

// Whether the wall along the refracted direction t (cos_t to the normal) is thin against the
// object: under half the chord through the inscribed ellipsoid (a bottle, a glass), or not (a
// solid: a paperweight, a lens, a pane, whose ellipsoid is as flat as the pane).
bool thin_walled(CubeObject c, vec3 p, vec3 t, float cos_t) {
    float chord = ellipsoid_exit(c, p, t);
    return chord <= 0.0 || c.extent.w / max(cos_t, 1e-3) < 0.5 * chord;
}

// Where a ray inside a solid, from its surface point q along t, leaves the inscribed ellipsoid: the
// exit point, the ray's direction there and the outward normal, its weight (the absorption over the
// length inside, Beer-Lambert), and whether it refracts out there; total internal reflection is
// followed up to VOLUME_BOUNCES times.
struct SolidExit {
    vec3 q;
    vec3 t;
    vec3 n;
    vec3 weight;
    bool leaves;
};

SolidExit solid_exit(CubeObject c, vec3 q, vec3 t, vec3 weight) {
    float ior = c.volume.a;
    for (int k = 0; k < VOLUME_BOUNCES; ++k) {
        float s = max(ellipsoid_exit(c, q, t), 0.0);
        q += s * t;
        weight *= exp(-c.volume.rgb * s);
        vec3 n = ellipsoid_normal(c, q, t);
        if (dot(t, n) > 0.0 && refract(t, -n, ior) != vec3(0.0))
            return SolidExit(q, t, n, weight, true);
        t = reflect(t, -n);  // total internal reflection: on to the next side
    }
    return SolidExit(q, t, ellipsoid_normal(c, q, t), vec3(0.0), false);
}

// A reflection sample d (world, out of the object) at p, outward normal n: the outer surface's F is
// the lobe's; a thin wall adds its inner surface, seen through the outer one, along the same
// direction: (1 - F)^2 F a^2 (a the wall's absorption), so the lobe's weight F times
// 1 + (1 - F)^2 a^2 (the first two terms of the slab's reflectance). A solid adds nothing here.
CubeLook volume_reflect(CubeObject c, vec3 p, vec3 n, vec3 d) {
    float ior = c.volume.a;
    float cos_i = clamp(dot(d, n), 0.0, 1.0);
    vec3 t = refract(reflect(d, n), n, 1.0 / ior);  // the light that entered: the refracted ray
    vec3 look = bounding_plane_direction(c, p, d);
    float cos_t = -dot(t, n);
    if (!(cos_i > 0.0) || !(cos_t > 0.0) || !thin_walled(c, p, t, cos_t))
        return single_look(look, vec3(1.0));
    float keep = 1.0 - fresnel_dielectric(cos_i, ior);
    vec3 a = exp(-c.volume.rgb * (c.extent.w / cos_t));
    return single_look(look, 1.0 + keep * keep * a * a);
}

// The sample direction d (world, into the object) at the point p with the outward normal n.
CubeLook volume_transmit(CubeObject c, vec3 p, vec3 n, vec3 d) {
    float ior = c.volume.a;
    vec3 sigma = c.volume.rgb;
    float cos_i = clamp(-dot(d, n), 0.0, 1.0);
    vec3 t = refract(d, n, 1.0 / ior);  // from air: never total internal reflection
    if (t == vec3(0.0) || !(cos_i > 0.0))
        return single_look(bounding_plane_direction(c, p, d), vec3(0.0));
    float cos_t = max(-dot(t, n), 1e-3);
    if (thin_walled(c, p, t, cos_t)) {
        // Two slabs, the direction unchanged: the near wall's inner surface (1 - F), then the far
        // wall, where the straight ray meets the ellipsoid, at its own angle: it transmits
        // (1 - F_b)^2 and reflects F_b + (1 - F_b)^2 F_b a_b^2 back through the near wall
        // ((1 - F)^2 again), towards reflect(d, far normal), looked up from the far point.
        float keep = 1.0 - fresnel_dielectric(cos_i, ior);
        vec3 a = exp(-sigma * (c.extent.w / cos_t));
        vec3 q = p + max(ellipsoid_exit(c, p, d), 0.0) * d;
        vec3 nb = ellipsoid_normal(c, q, d);  // the far wall's outward normal
        float cos_b = clamp(dot(d, nb), 0.0, 1.0);
        float fb = fresnel_dielectric(cos_b, ior);
        vec3 ab = exp(-sigma * (c.extent.w / max(sqrt(max(1.0 - (1.0 - cos_b * cos_b) / (ior * ior), 0.0)), 1e-3)));
        vec3 back = (1.0 - fb) * (1.0 - fb) * ab;
        vec3 echo = fb + back * fb * ab;
        vec3 r = reflect(d, nb);
        return CubeLook(bounding_plane_direction(c, p, d), keep * a * back,
                        bounding_plane_direction(c, q, r), keep * a * echo * keep * keep * a * a);
    }
    // Solid: out where the refracted ray leaves (1 - F_1), plus the light partially reflected there
    // (F_1), which crosses the solid again and leaves elsewhere (1 - F_2): for a sphere seen
    // head-on, what lies behind the viewer, at (1 - F)^2 F (3.7 % of it for n = 1.5).
    SolidExit first = solid_exit(c, p, t, vec3(1.0));
    if (!first.leaves)
        return single_look(bounding_plane_direction(c, first.q, first.t), vec3(0.0));  // trapped: lost
    float f1 = fresnel_dielectric(dot(first.t, first.n), 1.0 / ior);
    SolidExit echo = solid_exit(c, first.q, reflect(first.t, -first.n), first.weight * f1);
    float f2 = fresnel_dielectric(dot(echo.t, echo.n), 1.0 / ior);
    return CubeLook(bounding_plane_direction(c, first.q, refract(first.t, -first.n, ior)), first.weight * (1.0 - f1),
                    bounding_plane_direction(c, echo.q, refract(echo.t, -echo.n, ior)),
                    echo.leaves ? echo.weight * (1.0 - f2) : vec3(0.0));
}
