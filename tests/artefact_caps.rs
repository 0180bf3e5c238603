//! A tiny GLB that claims 10 million triangles is refused with `TooLarge` before the loader
//! allocates anything of that size: a counting global allocator measures the peak.
//! (Its own test binary, with a single test, so no other test's allocations interfere.)
#![cfg(feature = "gltf")]

mod artefact_support;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use parallax::artefact::{Artefact, LoadLimits, LoadOptions};
use parallax::Error;
use serde_json::json;

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::SeqCst) + layout.size();
            PEAK.fetch_max(now, Ordering::SeqCst);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Peak bytes allocated above the level at the start while running `f`.
fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let start = CURRENT.load(Ordering::SeqCst);
    PEAK.store(start, Ordering::SeqCst);
    let out = f();
    (out, PEAK.load(Ordering::SeqCst) - start)
}

#[test]
fn ten_million_triangles_over_the_cap_fail_before_allocating() {
    // One triangle's worth of real data; the accessors claim 30 M vertices and 30 M indices
    // (10 M triangles), and the buffer claims the bytes that would need.
    let vertices: u64 = 30_000_000;
    let positions: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let bin: Vec<u8> = bytemuck::cast_slice(&positions).to_vec();
    let claimed = vertices * 12 + vertices * 4;
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5125, "count": vertices, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": vertices * 12},
            {"buffer": 0, "byteOffset": vertices * 12, "byteLength": vertices * 4}
        ],
        "buffers": [{"byteLength": claimed}]
    });
    let bytes = artefact_support::glb(&doc, &bin);
    assert!(bytes.len() < 2000);

    let (result, peak) = peak_during(|| Artefact::from_glb_bytes(&bytes, &LoadOptions::default()));
    let e = result.unwrap_err();
    assert!(matches!(e, Error::TooLarge(_)), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("max_vertices") || msg.contains("max_triangles"),
        "{msg}"
    );
    // Parsing the JSON costs kilobytes; 10 M triangles would cost hundreds of megabytes.
    assert!(peak < 1 << 20, "peak allocation {peak} bytes");

    // With caps raised past the claim, the same file fails on its real size, still without
    // allocating what it claims: the buffer holds 36 bytes, not 480 MB.
    let limits = LoadLimits {
        max_vertices: 100_000_000,
        max_triangles: 100_000_000,
        max_total_bytes: 1 << 40,
        ..LoadLimits::default()
    };
    let (result, peak) = peak_during(|| Artefact::from_glb_bytes(&bytes, &LoadOptions { limits }));
    let e = result.unwrap_err();
    assert!(matches!(e, Error::Format(_)), "{e}");
    assert!(e.to_string().contains("buffer 0"), "{e}");
    assert!(peak < 1 << 20, "peak allocation {peak} bytes");

    // The default memory cap alone also refuses it.
    let limits = LoadLimits {
        max_vertices: 100_000_000,
        max_triangles: 100_000_000,
        max_total_bytes: 256 << 20,
        ..LoadLimits::default()
    };
    let e = Artefact::from_glb_bytes(&bytes, &LoadOptions { limits }).unwrap_err();
    assert!(e.to_string().contains("max_total_bytes"), "{e}");
}
