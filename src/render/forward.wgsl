// Artefact shading (premultiplied linear RGBA out): glTF metallic-roughness or the thesis'
// modified Blinn-Phong, every light with its shadow, SH9 ambient and split-sum specular.

// The scene mesh's depth-only draw shares the pass (and so its colour target) with the artefacts.
@fragment
fn fs_depth_only(v: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(0.0);
}

// Karis' analytic fit of the split-sum DFG terms (A, B), used without a DFG table.
fn env_brdf_approx(n_dot_v: f32, roughness: f32) -> vec2<f32> {
    let c0 = vec4<f32>(-1.0, -0.0275, -0.572, 0.022);
    let c1 = vec4<f32>(1.0, 0.0425, 1.04, -0.04);
    let r = roughness * c0 + c1;
    let a004 = min(r.x * r.x, exp2(-9.28 * n_dot_v)) * r.x + r.y;
    return vec2<f32>(-1.04, 1.04) * a004 + r.zw;
}

// glTF 2.0 Appendix B: (1 − F) c_diff / π + F D V, D = GGX, V = height-correlated Smith.
fn brdf_pbr(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, base: vec3<f32>, metallic: f32, roughness: f32) -> vec3<f32> {
    let h = safe_normalize(l + v, n);
    let n_dot_l = clamp(dot(n, l), 0.0, 1.0);
    let n_dot_v = clamp(dot(n, v), 1e-4, 1.0);
    let n_dot_h = clamp(dot(n, h), 0.0, 1.0);
    let v_dot_h = clamp(dot(v, h), 0.0, 1.0);
    // α = roughness², kept ≥ 1e-3 so a mirror's highlight stays finite.
    let alpha = max(roughness * roughness, 1e-3);
    let alpha2 = alpha * alpha;
    let f0 = vec3<f32>(0.04) * (1.0 - metallic) + base * metallic;
    let c_diff = base * (1.0 - metallic);
    let fresnel = f0 + (vec3<f32>(1.0) - f0) * pow(1.0 - v_dot_h, 5.0);
    let k = n_dot_h * n_dot_h * (alpha2 - 1.0) + 1.0;
    let ggx = alpha2 / (PI * k * k);
    let smith = 1.0 / ((n_dot_l + sqrt(alpha2 + (1.0 - alpha2) * n_dot_l * n_dot_l))
        * (n_dot_v + sqrt(alpha2 + (1.0 - alpha2) * n_dot_v * n_dot_v)));
    let diffuse = (vec3<f32>(1.0) - fresnel) * c_diff * (1.0 / PI);
    let specular = fresnel * (ggx * smith);
    return diffuse + specular;
}

// Thesis eq. 3.27–3.30 for one light, per unit irradiance: k_d (L·N + c_s k_s (R·V)^α c_f) / π
// with k_d the base colour, k_s = f0, α the Blinn-Phong power of the roughness
// (α = 2/r⁴ − 2), c_s = (α + 8)/8π, c_base = 1 − (R·V)⁵ and c_f = (c_base + 0.018)(1 − c_base).
fn brdf_thesis(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, base: vec3<f32>, metallic: f32, roughness: f32) -> vec3<f32> {
    let n_dot_l = clamp(dot(n, l), 0.0, 1.0);
    let r = reflect(-l, n);
    let r_dot_v = clamp(dot(r, v), 0.0, 1.0);
    let a = max(roughness * roughness, 1e-3);
    let power = clamp(2.0 / (a * a) - 2.0, 1.0, 1e4);
    let c_s = (power + 8.0) / (8.0 * PI);
    let c_base = 1.0 - pow(r_dot_v, 5.0);
    let c_f = (c_base + 0.018) * (1.0 - c_base);
    let k_s = vec3<f32>(0.04) * (1.0 - metallic) + base * metallic;
    return base * (vec3<f32>(n_dot_l) + c_s * k_s * pow(r_dot_v, power) * c_f) / PI;
}

fn specular_ambient(n: vec3<f32>, v: vec3<f32>, f0: vec3<f32>, roughness: f32) -> vec3<f32> {
    let n_dot_v = clamp(dot(n, v), 1e-4, 1.0);
    let r = reflect(-v, n);
    var pre: vec3<f32>;
    if (frame.flags.z > 0.5) {
        let lod = roughness * (frame.flags.z - 1.0);
        pre = textureSampleLevel(env_map, env_sampler, r, lod).rgb;
    } else {
        // No prefiltered map: the SH9's diffuse radiance around the reflection, a rough stand-in.
        pre = sh_diffuse(r);
    }
    var ab: vec2<f32>;
    if (frame.flags.w > 0.5) {
        ab = textureSampleLevel(dfg_lut, env_sampler, vec2<f32>(n_dot_v, roughness), 0.0).xy;
    } else {
        ab = env_brdf_approx(n_dot_v, roughness);
    }
    return pre * (f0 * ab.x + vec3<f32>(ab.y));
}

@fragment
fn fs_artefact(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    // Every texture is sampled before any branch (uniform control flow for derivatives).
    let base = material_base(in.uv0, in.uv1, in.color);
    let mr = textureSample(t_mr, s_mr, material_uv(1u, material.uv_set.y, in.uv0, in.uv1));
    let nt = textureSample(t_normal, s_normal, material_uv(2u, material.uv_set.z, in.uv0, in.uv1));
    let occ = textureSample(t_occlusion, s_occlusion, material_uv(3u, material.uv_set.w, in.uv0, in.uv1));
    let emi = textureSample(t_emissive, s_emissive, material_uv(4u, material.uv_set2.x, in.uv0, in.uv1));
    let dpdx_ = dpdx(in.world);
    let dpdy_ = dpdy(in.world);
    let duvdx = dpdx(in.uv0);
    let duvdy = dpdy(in.uv0);

    let alpha = material_alpha(base.a);
    if (alpha < 0.0) {
        discard;
    }
    let v = safe_normalize(-in.world, vec3<f32>(0.0, 0.0, 1.0));
    var ng = safe_normalize(in.normal, v);
    if (!front) {
        ng = -ng;
    }
    var n = ng;
    if (material.alpha.z > 0.5) {
        var t = in.tangent.xyz;
        var w = in.tangent.w;
        if (dot(t, t) < 1e-12) {
            // No tangents: derive them from screen-space derivatives of position and uv.
            let det = duvdx.x * duvdy.y - duvdy.x * duvdx.y;
            t = (dpdx_ * duvdy.y - dpdy_ * duvdx.y) * select(1.0, -1.0, det < 0.0);
            w = select(1.0, -1.0, det < 0.0);
        }
        t = safe_normalize(t - ng * dot(ng, t), vec3<f32>(1.0, 0.0, 0.0));
        let b = cross(ng, t) * select(1.0, -1.0, w < 0.0);
        let tn = (nt.xyz * 2.0 - vec3<f32>(1.0)) * vec3<f32>(material.params.z, material.params.z, 1.0);
        n = safe_normalize(t * tn.x + b * tn.y + ng * tn.z, ng);
    }
    let metallic = clamp(material.params.x * mr.b, 0.0, 1.0);
    let roughness = clamp(material.params.y * mr.g, 0.0, 1.0);
    let ao = 1.0 + material.params.w * (occ.r - 1.0);
    let albedo = base.rgb;
    let thesis = frame.counts.z == 1u;

    var color = vec3<f32>(0.0);
    for (var i = 0u; i < frame.counts.x; i++) {
        let s = light_sample(lights[i], in.world);
        if (dot(n, s.l) <= 0.0 && dot(ng, s.l) <= 0.0) {
            continue;
        }
        var vis = vec2<f32>(1.0);
        if (in.receives_shadow > 0.5) {
            vis = shadow_visibility(i, in.world, ng);
        }
        var f: vec3<f32>;
        if (thesis) {
            f = brdf_thesis(n, v, s.l, albedo, metallic, roughness);
        } else {
            f = brdf_pbr(n, v, s.l, albedo, metallic, roughness) * clamp(dot(n, s.l), 0.0, 1.0);
        }
        color += f * s.e * (vis.x * vis.y);
    }
    if (thesis) {
        color += albedo * sh_diffuse(n) * ao;
    } else {
        let c_diff = albedo * (1.0 - metallic);
        let f0 = vec3<f32>(0.04) * (1.0 - metallic) + albedo * metallic;
        color += c_diff * sh_diffuse(n) * ao;
        // Split-sum specular only where the material can show a reflection.
        if (roughness < 0.95 || metallic > 0.0) {
            color += specular_ambient(n, v, f0, roughness) * ao;
        }
    }
    color += material.emissive.rgb * emi.rgb;
    // f16 target: clamp so a light inside an artefact or a mirror highlight stays finite.
    color = clamp(color, vec3<f32>(0.0), vec3<f32>(60000.0));
    return vec4<f32>(color * alpha, alpha);
}
