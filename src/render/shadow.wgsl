// Shadow-map pass: linear distance from the light (metres) of the nearest caster per texel.

// Set for 16-bit targets (`TargetFormats::split_shadow_distance`): the distance is written as
// its f16 rounding plus the remainder, which the lookup adds back.
override SPLIT_DISTANCE: bool = false;

struct ShadowPass {
    view_proj: mat4x4<f32>,
    // light position or near-plane point, 1 when orthographic
    origin_ortho: vec4<f32>,
    // direction (orthographic)
    axis: vec4<f32>,
};

@group(0) @binding(0) var<uniform> pass_: ShadowPass;

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
    @location(1) uv0: vec2<f32>,
    @location(2) uv1: vec2<f32>,
    @location(3) color: vec4<f32>,
};

@vertex
fn vs_shadow(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = pass_.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.uv0 = v.uv0;
    out.uv1 = v.uv1;
    out.color = v.color;
    return out;
}

@fragment
fn fs_shadow(v: VertexOut) -> @location(0) vec4<f32> {
    let base = material_base(v.uv0, v.uv1, v.color);
    let mode = u32(material.alpha.x + 0.5);
    // MASK casts where it is drawn; BLEND casts where it is at least half opaque.
    if ((mode == 1u && base.a < material.alpha.y) || (mode == 2u && base.a < 0.5)) {
        discard;
    }
    var d: f32;
    if (pass_.origin_ortho.w > 0.5) {
        d = dot(v.world - pass_.origin_ortho.xyz, pass_.axis.xyz);
    } else {
        d = length(v.world - pass_.origin_ortho.xyz);
    }
    if (SPLIT_DISTANCE && d < 65504.0) {
        let high = quantizeToF16(d);
        return vec4<f32>(high, d - high, 0.0, 1.0);
    }
    return vec4<f32>(d, 0.0, 0.0, 1.0);
}
