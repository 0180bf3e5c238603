// A red triangle with NDC corners (-1,-1), (0,-1), (-1,1), used by the readback test.
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    var corners = array<vec2<f32>, 3>(vec2(-1.0, -1.0), vec2(0.0, -1.0), vec2(-1.0, 1.0));
    return vec4<f32>(corners[i], 0.0, 1.0);
}

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.0, 0.0, 1.0);
}
