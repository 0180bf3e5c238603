// Differential rendering onto the photo: per pixel, the shading of the scene mesh (white
// Lambertian) with the artefacts over the shading without them; and the artefacts' depth.

struct ReceiverOut {
    @location(0) ratio: vec4<f32>,
    @location(1) depth: vec4<f32>,
};

// Fraction of the ambient (cosine-weighted) hemisphere at p, normal n, that the artefacts'
// spheres cover: (r/d)² cos θ per sphere (the projected solid angle of a sphere wholly above
// the horizon), combined as independent occluders.
fn artefact_ambient_occlusion(p: vec3<f32>, n: vec3<f32>) -> f32 {
    var open = 1.0;
    for (var i = 0u; i < frame.counts.y; i++) {
        let s = spheres[i];
        let d = s.xyz - p;
        let dist2 = max(dot(d, d), 1e-30);
        let r2 = s.w * s.w;
        let cos_t = dot(n, d) * inverseSqrt(dist2);
        let o = clamp(cos_t * r2 / max(dist2, r2), 0.0, 1.0);
        open *= 1.0 - o;
    }
    return 1.0 - open;
}

@fragment
fn fs_receiver(in: VertexOut) -> ReceiverOut {
    var out: ReceiverOut;
    out.depth = vec4<f32>(0.0);
    let v = safe_normalize(-in.world, vec3<f32>(0.0, 0.0, 1.0));
    var n = safe_normalize(in.normal, v);
    if (dot(n, v) < 0.0) {
        n = -n;
    }
    // Where the photo already shows shadow, its direct light is already missing: take it out of
    // both terms so the artefacts cannot darken it again.
    var direct_weight = 1.0;
    if (frame.flags.y > 0.5) {
        let px = vec2<i32>(floor(in.clip.xy));
        direct_weight = 1.0 - clamp(textureLoad(photo_mask, px, 0).r, 0.0, 1.0);
    }
    var with_ = vec3<f32>(0.0);
    var without = vec3<f32>(0.0);
    for (var i = 0u; i < frame.counts.x; i++) {
        let s = light_sample(lights[i], in.world);
        let cos_l = dot(n, s.l);
        if (cos_l <= 0.0) {
            continue;
        }
        let vis = shadow_visibility(i, in.world, n);
        let e = s.e * (cos_l * direct_weight * vis.y / PI);
        without += e;
        with_ += e * vis.x;
    }
    let ambient = sh_diffuse(n);
    var occlusion = 0.0;
    if (frame.counts.y > 0u) {
        occlusion = artefact_ambient_occlusion(in.world, n);
    }
    with_ += ambient * (1.0 - occlusion);
    without += ambient;
    var ratio = vec3<f32>(1.0);
    for (var k = 0; k < 3; k++) {
        if (without[k] > 1e-20) {
            ratio[k] = clamp(with_[k] / without[k], 0.0, 1.0);
        }
    }
    out.ratio = vec4<f32>(ratio, 1.0);
    return out;
}

// Opaque and masked artefacts write their depth (metres along the optical axis).
@fragment
fn fs_artefact_depth(in: VertexOut) -> ReceiverOut {
    var out: ReceiverOut;
    let base = material_base(in.uv0, in.uv1, in.color);
    if (material_alpha(base.a) < 0.0) {
        discard;
    }
    out.ratio = vec4<f32>(1.0);
    out.depth = vec4<f32>(-in.world.z, 0.0, 0.0, 1.0);
    return out;
}
