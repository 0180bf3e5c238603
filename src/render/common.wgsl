// Shared by the forward (artefact) and receiver (shadow ratio) passes: frame data, lights,
// shadow-map lookups and the light and ambient terms. Every exponential is taken of a bounded
// argument, so no value here can overflow to infinity or become NaN.

struct Frame {
    view_proj: mat4x4<f32>,
    sh: array<vec4<f32>, 9>,
    // width, height, unused, unused
    size: vec4<f32>,
    // light count, occluder sphere count, shading mode (0 PBR, 1 thesis), shadow mode
    // (0 thesis ESM, 1 EVSM, 2 PCSS, 3 off)
    counts: vec4<u32>,
    // filter radius (texels), thesis c, EVSM c+, EVSM c-
    shadow: vec4<f32>,
    // shadow-map size, photo shadow mask present, environment mip count (0 = none), DFG present
    flags: vec4<f32>,
};

struct GpuLight {
    // position, kind (0 directional, 1 point, 2 area)
    pos_kind: vec4<f32>,
    // direction of travel, emitter radius in metres (point, area)
    dir_radius: vec4<f32>,
    intensity: vec4<f32>,
    // first shadow view, view count (0 = unshadowed, 1, or 6 for a cube)
    shadow: vec4<i32>,
};

struct GpuView {
    view_proj: mat4x4<f32>,
    // light position or near-plane point, 1 when orthographic
    origin_ortho: vec4<f32>,
    // direction (orthographic), near distance
    axis_near: vec4<f32>,
    // far distance, uv per metre, light radius (m) or tan(half angle), unused
    params: vec4<f32>,
    // layer of the artefacts' map, layer of the scene mesh's map (-1 = none)
    layers: vec4<i32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> lights: array<GpuLight>;
@group(0) @binding(2) var<storage, read> views: array<GpuView>;
@group(0) @binding(3) var shadow_maps: texture_2d_array<f32>;
@group(0) @binding(4) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(5) var env_map: texture_cube<f32>;
@group(0) @binding(6) var dfg_lut: texture_2d<f32>;
@group(0) @binding(7) var env_sampler: sampler;
@group(0) @binding(8) var photo_mask: texture_2d<f32>;

const PI: f32 = 3.14159265;
// Largest irradiance a light may deliver; keeps products with the BRDF finite in f32.
const MAX_IRRADIANCE: f32 = 1e20;
// Largest exponent argument taken: e^40 squared and summed over 289 taps stays below f32's max.
const MAX_EXP_ARG: f32 = 40.0;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) receives_shadow: f32,
    @location(2) normal: vec3<f32>,
    @location(3) tangent: vec4<f32>,
    @location(4) uv0: vec2<f32>,
    @location(5) uv1: vec2<f32>,
    @location(6) color: vec4<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent: vec4<f32>,
    @location(3) uv0: vec2<f32>,
    @location(4) uv1: vec2<f32>,
    @location(5) color: vec4<f32>,
    @location(6) receives_shadow: f32,
};

@vertex
fn vs_camera(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.tangent = v.tangent;
    out.uv0 = v.uv0;
    out.uv1 = v.uv1;
    out.color = v.color;
    out.receives_shadow = v.receives_shadow;
    return out;
}

// Diffuse radiance of a white Lambertian surface (Filament's pre-scaled SH9 polynomial).
fn sh_diffuse(n: vec3<f32>) -> vec3<f32> {
    let p = array<f32, 9>(
        1.0, n.y, n.z, n.x, n.x * n.y, n.y * n.z, 3.0 * n.z * n.z - 1.0, n.x * n.z,
        n.x * n.x - n.y * n.y
    );
    var c = vec3<f32>(0.0);
    for (var i = 0u; i < 9u; i++) {
        c += frame.sh[i].rgb * p[i];
    }
    return max(c, vec3<f32>(0.0));
}

fn safe_normalize(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l2 = dot(v, v);
    if (l2 > 1e-30) {
        return v * inverseSqrt(l2);
    }
    return fallback;
}

struct LightSample {
    // unit direction towards the light
    l: vec3<f32>,
    // irradiance on a surface facing the light
    e: vec3<f32>,
};

fn light_sample(li: GpuLight, p: vec3<f32>) -> LightSample {
    var s: LightSample;
    let kind = i32(li.pos_kind.w + 0.5);
    if (kind == 0) {
        s.l = safe_normalize(-li.dir_radius.xyz, vec3<f32>(0.0, 1.0, 0.0));
        s.e = li.intensity.rgb;
        return s;
    }
    let d = li.pos_kind.xyz - p;
    let r2 = dot(d, d);
    let radius = li.dir_radius.w;
    s.l = safe_normalize(d, vec3<f32>(0.0, 1.0, 0.0));
    var denom: f32;
    var falloff = 1.0;
    if (kind == 1) {
        // A sphere of radius R gives I / r² outside; inside, its irradiance saturates at I / R².
        denom = max(r2, radius * radius);
    } else {
        // A Lambertian disc on its axis gives exactly I / (r² + R²); off axis the cosine.
        denom = r2 + radius * radius;
        falloff = max(dot(safe_normalize(li.dir_radius.xyz, vec3<f32>(0.0, -1.0, 0.0)), -s.l), 0.0);
    }
    s.e = min(li.intensity.rgb * (falloff / max(denom, 1e-30)), vec3<f32>(MAX_IRRADIANCE));
    return s;
}

// ---- shadow maps -------------------------------------------------------------------------

fn view_distance(v: GpuView, p: vec3<f32>) -> f32 {
    if (v.origin_ortho.w > 0.5) {
        return dot(p - v.origin_ortho.xyz, v.axis_near.xyz);
    }
    return length(p - v.origin_ortho.xyz);
}

// World size of one shadow-map texel at distance `dist` from the light.
fn texel_world(v: GpuView, dist: f32) -> f32 {
    let per_texel = 1.0 / max(v.params.y * frame.flags.x, 1e-30);
    if (v.origin_ortho.w > 0.5) {
        return per_texel;
    }
    return per_texel * dist;
}

fn load_depth(layer: i32, t: vec2<i32>) -> f32 {
    let size = i32(frame.flags.x);
    let c = clamp(t, vec2<i32>(0), vec2<i32>(size - 1));
    // Red and green add up to the distance (green is 0 unless the map is split over two
    // 16-bit channels, see shadow.wgsl).
    let texel = textureLoad(shadow_maps, c, layer, 0);
    return texel.r + texel.g;
}

// Eq. 3.36–3.38: per tap, 1 where the receiver is not behind the occluder, else
// 1 − exp(−c·diff) with diff the normalised depth behind it (so contact is dark and the shadow
// fades with distance from its caster); averaged over the (2r+1)² box (eq. 3.35's filter).
// exp() only ever sees −c·diff ≤ 0: no overflow for any c.
fn thesis_esm(layer: i32, center: vec2<i32>, z: f32, range: f32) -> f32 {
    let r = i32(frame.shadow.x);
    let c = frame.shadow.y;
    var sum = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let d = load_depth(layer, center + vec2<i32>(dx, dy));
            let diff = (z - d) / range;
            var vis = 1.0;
            if (diff > 0.0) {
                vis = 1.0 - exp(-min(c * diff, 80.0));
            }
            sum += vis;
        }
    }
    let n = f32((2 * r + 1) * (2 * r + 1));
    return sum / n;
}

fn chebyshev(m1: f32, m2: f32, t: f32, min_var: f32) -> f32 {
    if (t <= m1) {
        return 1.0;
    }
    let var_ = max(m2 - m1 * m1, min_var);
    let d = t - m1;
    return var_ / (var_ + d * d);
}

// EVSM over the (2r+1)² box. The warps are taken of (occluder − receiver) in normalised depth,
// so the receiver's own warped depth is e⁰ = 1 and −1: Chebyshev's bound is invariant to that
// shift, and the arguments are clamped to ±MAX_EXP_ARG, so no moment can overflow whatever c.
fn evsm(layer: i32, center: vec2<i32>, z: f32, range: f32) -> f32 {
    let r = i32(frame.shadow.x);
    let cp = frame.shadow.z;
    let cn = frame.shadow.w;
    var m = vec4<f32>(0.0);
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let d = load_depth(layer, center + vec2<i32>(dx, dy));
            let dd = (d - z) / range;
            let p = exp(clamp(cp * dd, -MAX_EXP_ARG, MAX_EXP_ARG));
            let q = -exp(clamp(-cn * dd, -MAX_EXP_ARG, MAX_EXP_ARG));
            m += vec4<f32>(p, p * p, q, q * q);
        }
    }
    m /= f32((2 * r + 1) * (2 * r + 1));
    // Minimum variance: the warp of a depth error of 1e-3 of the range.
    let vp = chebyshev(m.x, m.y, 1.0, max(cp * cp * 1e-6, 1e-10));
    let vn = chebyshev(m.z, m.w, -1.0, max(cn * cn * 1e-6, 1e-10));
    // Light-bleeding reduction: cut the tail of the bound.
    return clamp((min(vp, vn) - 0.15) / 0.85, 0.0, 1.0);
}

// Penumbra radius in shadow-map uv for a receiver at `z` and a blocker at `d` (metres):
// light size × (z − d) / d, projected at the receiver.
fn penumbra_uv(v: GpuView, z: f32, d: f32) -> f32 {
    if (v.origin_ortho.w > 0.5) {
        return max(z - d, 0.0) * v.params.z * v.params.y;
    }
    return v.params.z * max(z - d, 0.0) / max(d, 1e-30) * v.params.y / max(z, 1e-30);
}

fn pcss(v: GpuView, layer: i32, uv: vec2<f32>, z: f32) -> f32 {
    let size = frame.flags.x;
    let max_texels = 24.0;
    // Blocker search over the region a blocker halfway to the light could shadow from.
    let search = clamp(penumbra_uv(v, z, 0.5 * z) * size, 1.0, max_texels);
    var blockers = 0.0;
    var sum = 0.0;
    for (var j = -3; j <= 3; j++) {
        for (var i = -3; i <= 3; i++) {
            let t = vec2<i32>(floor(uv * size + vec2<f32>(f32(i), f32(j)) * search / 3.0));
            let d = load_depth(layer, t);
            if (d < z) {
                blockers += 1.0;
                sum += d;
            }
        }
    }
    if (blockers == 0.0) {
        return 1.0;
    }
    let avg = sum / blockers;
    let radius = clamp(penumbra_uv(v, z, avg) * size, max(frame.shadow.x, 0.5), max_texels);
    var lit = 0.0;
    for (var j = -3; j <= 3; j++) {
        for (var i = -3; i <= 3; i++) {
            let t = vec2<i32>(floor(uv * size + vec2<f32>(f32(i), f32(j)) * radius / 3.0));
            if (load_depth(layer, t) >= z) {
                lit += 1.0;
            }
        }
    }
    return lit / 49.0;
}

fn filtered_visibility(v: GpuView, layer: i32, uv: vec2<f32>, z: f32) -> f32 {
    if (layer < 0) {
        return 1.0;
    }
    let mode = frame.counts.w;
    let range = max(v.params.x - v.axis_near.w, 1e-30);
    let center = vec2<i32>(floor(uv * frame.flags.x));
    if (mode == 0u) {
        return thesis_esm(layer, center, z, range);
    }
    if (mode == 1u) {
        return evsm(layer, center, z, range);
    }
    return pcss(v, layer, uv, z);
}

// Visibility of light `index` at `p` with geometric normal `n`: (by the artefacts, by the scene
// mesh), each in [0, 1].
fn shadow_visibility(index: u32, p: vec3<f32>, n: vec3<f32>) -> vec2<f32> {
    let li = lights[index];
    if (li.shadow.y == 0 || frame.counts.w == 3u) {
        return vec2<f32>(1.0);
    }
    var vi = li.shadow.x;
    if (li.shadow.y == 6) {
        let d = p - li.pos_kind.xyz;
        let a = abs(d);
        var face = 0;
        if (a.x >= a.y && a.x >= a.z) {
            face = select(1, 0, d.x >= 0.0);
        } else if (a.y >= a.z) {
            face = select(3, 2, d.y >= 0.0);
        } else {
            face = select(5, 4, d.z >= 0.0);
        }
        vi += face;
    }
    let v = views[vi];
    let tw = texel_world(v, max(view_distance(v, p), 0.0));
    // Normal offset against acne: move the receiver one and a half texels off its surface, on
    // the side facing the light.
    let ls = light_sample(li, p);
    let side = select(-1.0, 1.0, dot(n, ls.l) >= 0.0);
    let q = p + n * side * tw * 1.5;
    let clip = v.view_proj * vec4<f32>(q, 1.0);
    if (clip.w <= 0.0) {
        return vec2<f32>(1.0);
    }
    let ndc = clip.xyz / clip.w;
    if (abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0) {
        return vec2<f32>(1.0);
    }
    let uv = vec2<f32>(0.5 * ndc.x + 0.5, 0.5 - 0.5 * ndc.y);
    let z = view_distance(v, q) - tw;
    return vec2<f32>(
        filtered_visibility(v, v.layers.x, uv, z),
        filtered_visibility(v, v.layers.y, uv, z),
    );
}
