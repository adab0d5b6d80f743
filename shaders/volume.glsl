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
//   internal reflection followed up to VOLUME_BOUNCES times), absorbed over its length inside.
// The look-up then starts from the exit point (bounding planes, section 4.4.1).

#include "common.glsl"

const int VOLUME_BOUNCES = 3;

struct CubeLook {
    vec3 dir;     // the look-up direction in the object's cube map
    vec3 weight;  // what the glass lets through of the radiance found there
};

bool has_volume(CubeObject c) {
    return c.volume.a > 0.0;
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

// The far intersection s > 0 of p + s d with the ellipsoid of half axes h around `centre`, or -1.
float ellipsoid_exit(vec3 p, vec3 d, vec3 centre, vec3 h) {
    vec3 o = (p - centre) / h;
    vec3 v = d / h;
    float a = dot(v, v), b = dot(o, v), c = dot(o, o) - 1.0;
    float disc = b * b - a * c;
    if (!(disc >= 0.0) || !(a > 0.0))
        return -1.0;
    return (-b + sqrt(disc)) / a;
}

// The sample direction d (world, into the object) at the point p with the outward normal n.
CubeLook volume_transmit(CubeObject c, vec3 p, vec3 n, vec3 d) {
    float ior = c.volume.a;
    vec3 sigma = c.volume.rgb;
    vec3 h = max(c.extent.xyz, vec3(1e-4));
    float cos_i = clamp(-dot(d, n), 0.0, 1.0);
    vec3 t = refract(d, n, 1.0 / ior);  // from air: never total internal reflection
    if (t == vec3(0.0) || !(cos_i > 0.0))
        return CubeLook(bounding_plane_direction(c, p, d), vec3(0.0));
    float cos_t = max(-dot(t, n), 1e-3);
    float wall = c.extent.w / cos_t;
    float chord = ellipsoid_exit(p, t, c.centre.xyz, h);
    if (chord <= 0.0 || wall < 0.5 * chord) {  // thin-walled: two slabs, the direction unchanged
        float keep = 1.0 - fresnel_dielectric(cos_i, ior);
        return CubeLook(bounding_plane_direction(c, p, d), keep * keep * keep * exp(-sigma * (2.0 * wall)));
    }
    vec3 q = p;
    vec3 weight = vec3(1.0);
    for (int k = 0; k < VOLUME_BOUNCES; ++k) {
        float s = max(ellipsoid_exit(q, t, c.centre.xyz, h), 0.0);
        q += s * t;
        weight *= exp(-sigma * s);
        vec3 ne = safe_normalize((q - c.centre.xyz) / (h * h), t);  // the ellipsoid's outward normal
        float cos_out = dot(t, ne);
        vec3 out_dir = refract(t, -ne, ior);
        if (cos_out > 0.0 && out_dir != vec3(0.0))
            return CubeLook(bounding_plane_direction(c, q, out_dir),
                            weight * (1.0 - fresnel_dielectric(cos_out, 1.0 / ior)));
        t = reflect(t, -ne);  // total internal reflection: on to the next side
    }
    return CubeLook(bounding_plane_direction(c, q, t), vec3(0.0));  // trapped: lost
}
