//! Uniform and storage layouts shared with the WGSL (`common.wgsl`, `material.wgsl`,
//! `shadow.wgsl`); field order and sizes must match them.

use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct FrameU {
    pub view_proj: [[f32; 4]; 4],
    pub sh: [[f32; 4]; 9],
    pub size: [f32; 4],
    pub counts: [u32; 4],
    pub shadow: [f32; 4],
    pub flags: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct LightU {
    pub pos_kind: [f32; 4],
    pub dir_radius: [f32; 4],
    pub intensity: [f32; 4],
    pub shadow: [i32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct ViewU {
    pub view_proj: [[f32; 4]; 4],
    pub origin_ortho: [f32; 4],
    pub axis_near: [f32; 4],
    pub params: [f32; 4],
    pub layers: [i32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct MaterialU {
    pub base_color: [f32; 4],
    pub emissive: [f32; 4],
    pub params: [f32; 4],
    pub alpha: [f32; 4],
    pub uv_set: [u32; 4],
    pub uv_set2: [u32; 4],
    pub xf: [[f32; 4]; 10],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct ShadowPassU {
    pub view_proj: [[f32; 4]; 4],
    pub origin_ortho: [f32; 4],
    pub axis: [f32; 4],
}
