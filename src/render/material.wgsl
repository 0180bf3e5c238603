// A glTF metallic-roughness material: factors, five textures with their coordinate set and
// KHR_texture_transform, alpha mode.

struct MaterialU {
    base_color: vec4<f32>,
    // emissive × strength, unused
    emissive: vec4<f32>,
    // metallic, roughness, normal scale, occlusion strength
    params: vec4<f32>,
    // alpha mode (0 opaque, 1 mask, 2 blend), cutoff, has normal map, unused
    alpha: vec4<f32>,
    // texture coordinate set of base colour, metallic-roughness, normal, occlusion
    uv_set: vec4<u32>,
    // of emissive; unused ×3
    uv_set2: vec4<u32>,
    // per slot two rows of the 2×3 uv transform
    xf: array<vec4<f32>, 10>,
};

@group(1) @binding(0) var<uniform> material: MaterialU;
@group(1) @binding(1) var t_base: texture_2d<f32>;
@group(1) @binding(2) var t_mr: texture_2d<f32>;
@group(1) @binding(3) var t_normal: texture_2d<f32>;
@group(1) @binding(4) var t_occlusion: texture_2d<f32>;
@group(1) @binding(5) var t_emissive: texture_2d<f32>;
@group(1) @binding(6) var s_base: sampler;
@group(1) @binding(7) var s_mr: sampler;
@group(1) @binding(8) var s_normal: sampler;
@group(1) @binding(9) var s_occlusion: sampler;
@group(1) @binding(10) var s_emissive: sampler;

fn material_uv(slot: u32, uv_set: u32, uv0: vec2<f32>, uv1: vec2<f32>) -> vec2<f32> {
    let uv = select(uv0, uv1, uv_set == 1u);
    let r0 = material.xf[2u * slot];
    let r1 = material.xf[2u * slot + 1u];
    return vec2<f32>(dot(r0.xyz, vec3<f32>(uv, 1.0)), dot(r1.xyz, vec3<f32>(uv, 1.0)));
}

// Base colour × vertex colour (linear RGBA; the texture is sRGB-decoded by its format).
fn material_base(uv0: vec2<f32>, uv1: vec2<f32>, color: vec4<f32>) -> vec4<f32> {
    let t = textureSample(t_base, s_base, material_uv(0u, material.uv_set.x, uv0, uv1));
    return material.base_color * t * color;
}

// Alpha after the material's mode: < 0 means the fragment is cut away (MASK).
fn material_alpha(alpha: f32) -> f32 {
    let mode = u32(material.alpha.x + 0.5);
    if (mode == 0u) {
        return 1.0;
    }
    if (mode == 1u) {
        return select(-1.0, 1.0, alpha >= material.alpha.y);
    }
    return clamp(alpha, 0.0, 1.0);
}
