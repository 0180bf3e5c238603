//! Property test: mutated glTF/GLB files (byte flips, truncations, insertions, JSON field edits,
//! huge counts) never panic or hang the loader, and whatever loads satisfies the output
//! invariants (indices in range, finite unit normals, finite positions, valid material and
//! texture references).
//!
//! The normal suite runs a fixed, seeded batch (a few seconds). The long run is ignored by
//! default: `PARALLAX_FUZZ_SECS=180 cargo test --release --test artefact_fuzz -- --ignored
//! --nocapture` (default 180 s).
#![cfg(feature = "gltf")]

mod artefact_support;

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use parallax::artefact::{Artefact, LoadLimits, LoadOptions};
use serde_json::{json, Value};

/// xorshift64* (Vigna 2016): tiny, seeded, good enough to pick mutations.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.next() % 100 < percent
    }
}

/// A valid asset to mutate: its JSON, its binary chunk (GLB when present), and the folder its
/// external files live in.
#[derive(Clone)]
struct Seed {
    name: String,
    json: Value,
    bin: Option<Vec<u8>>,
    folder: Option<PathBuf>,
}

fn seeds(include_data: bool, max_file_bytes: u64) -> Vec<Seed> {
    let boxed = artefact_support::textured_box(0.5, [0.1, 0.2, 0.3]);
    let mut normal_mapped = boxed.json.clone();
    normal_mapped["materials"][0]["normalTexture"] = json!({"index": 0});
    normal_mapped["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
        json!({"KHR_texture_transform": {"offset": [0.5, 0.5], "rotation": 1.0}});
    normal_mapped["extensionsUsed"] = json!(["KHR_texture_transform"]);
    let embedded: Value = serde_json::from_slice(&boxed.gltf_embedded()).unwrap();
    let mut out = vec![
        Seed {
            name: "textured box (GLB)".into(),
            json: boxed.json.clone(),
            bin: Some(boxed.bin.clone()),
            folder: None,
        },
        Seed {
            name: "normal-mapped box (GLB)".into(),
            json: normal_mapped,
            bin: Some(boxed.bin.clone()),
            folder: None,
        },
        Seed {
            name: "textured box (embedded .gltf)".into(),
            json: embedded,
            bin: None,
            folder: None,
        },
    ];
    if include_data {
        if let Some(dir) = artefact_support::data_dir() {
            let mut stack = vec![dir];
            while let Some(d) = stack.pop() {
                let Ok(entries) = std::fs::read_dir(&d) else {
                    continue;
                };
                for e in entries.flatten() {
                    let p = e.path();
                    if p.is_dir() {
                        stack.push(p);
                        continue;
                    }
                    let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
                    let small = p
                        .metadata()
                        .map(|m| m.len() <= max_file_bytes)
                        .unwrap_or(false);
                    if !small || !(ext == "gltf" || ext == "glb") {
                        continue;
                    }
                    let bytes = std::fs::read(&p).unwrap();
                    let Some(seed) = split(&bytes) else { continue };
                    out.push(Seed {
                        name: p.display().to_string(),
                        json: seed.0,
                        bin: seed.1,
                        folder: p.parent().map(PathBuf::from),
                    });
                }
            }
        }
    }
    out
}

/// JSON and BIN chunk of a GLB or a .gltf file (test-side parser: plain offsets).
fn split(bytes: &[u8]) -> Option<(Value, Option<Vec<u8>>)> {
    if bytes.starts_with(b"glTF") {
        let jl = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        let json = serde_json::from_slice(bytes.get(20..20 + jl)?).ok()?;
        let rest = bytes.get(20 + jl..)?;
        let bin = if rest.len() >= 8 {
            let bl = u32::from_le_bytes(rest[0..4].try_into().ok()?) as usize;
            Some(rest.get(8..8 + bl)?.to_vec())
        } else {
            None
        };
        Some((json, bin))
    } else {
        serde_json::from_slice(bytes).ok().map(|j| (j, None))
    }
}

/// Every JSON pointer in `v`.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, c) in m {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(c, p, out);
            }
        }
        Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(c, p, out);
            }
        }
        _ => {}
    }
}

const INTERESTING: &[i64] = &[
    0, 1, -1, 2, 3, 4, 5, 7, 255, 256, 65535, 65536, 2147483647, 4294967295, 4294967296,
    10_000_000, 30_000_000, 5120, 5121, 5122, 5123, 5125, 5126,
];

fn interesting_value(rng: &mut Rng) -> Value {
    match rng.below(8) {
        0 => json!(1e30),
        1 => json!(-1e-30),
        2 => json!("VEC4"),
        3 => json!(null),
        4 => json!([]),
        5 => json!({}),
        6 => json!(rng.next() % 1000),
        _ => json!(INTERESTING[rng.below(INTERESTING.len())]),
    }
}

/// One structural edit of the JSON.
fn edit_json(json: &mut Value, rng: &mut Rng) {
    let mut all = Vec::new();
    pointers(json, String::new(), &mut all);
    if all.is_empty() {
        return;
    }
    // Counts, offsets, lengths and indices are where validation matters most: favour them.
    let numeric: Vec<&String> = all
        .iter()
        .filter(|p| json.pointer(p).is_some_and(Value::is_number))
        .collect();
    let target = if !numeric.is_empty() && rng.chance(70) {
        numeric[rng.below(numeric.len())].clone()
    } else {
        all[rng.below(all.len())].clone()
    };
    match rng.below(10) {
        0 => {
            // Remove the field or element.
            if let Some((parent, key)) = target.rsplit_once('/') {
                match json.pointer_mut(parent) {
                    Some(Value::Object(m)) => {
                        m.remove(&key.replace("~1", "/").replace("~0", "~"));
                    }
                    Some(Value::Array(a)) => {
                        if let Ok(i) = key.parse::<usize>() {
                            if i < a.len() {
                                a.remove(i);
                            }
                        }
                    }
                    _ => {}
                }
            }
        }
        1 => {
            // Duplicate an array element (extra children, scene roots, primitives…).
            if let Some((parent, key)) = target.rsplit_once('/') {
                if let Some(Value::Array(a)) = json.pointer_mut(parent) {
                    if let Ok(i) = key.parse::<usize>() {
                        if let Some(v) = a.get(i).cloned() {
                            a.push(v);
                        }
                    }
                }
            }
        }
        2 => {
            // A node becomes its own ancestor's child.
            if let Some(Value::Array(nodes)) = json.get_mut("nodes") {
                let n = nodes.len();
                if n > 0 {
                    let i = rng.below(n);
                    let c = rng.below(n);
                    if let Some(obj) = nodes[i].as_object_mut() {
                        obj.insert("children".into(), json!([c]));
                    }
                }
            }
        }
        _ => {
            let v = interesting_value(rng);
            if let Some(slot) = json.pointer_mut(&target) {
                *slot = v;
            }
        }
    }
}

fn mutate(seed: &Seed, rng: &mut Rng) -> Vec<u8> {
    let mut json = seed.json.clone();
    let mut bin = seed.bin.clone();
    if rng.chance(60) {
        for _ in 0..1 + rng.below(3) {
            edit_json(&mut json, rng);
        }
    }
    if let Some(b) = bin.as_mut() {
        if rng.chance(30) && !b.is_empty() {
            for _ in 0..1 + rng.below(8) {
                let i = rng.below(b.len());
                b[i] ^= 1 << rng.below(8);
            }
        }
    }
    let mut bytes = match &bin {
        Some(b) => artefact_support::glb(&json, b),
        None => serde_json::to_vec(&json).unwrap(),
    };
    match rng.below(10) {
        0 => {
            let cut = rng.below(bytes.len() + 1);
            bytes.truncate(cut);
        }
        1 | 2 => {
            for _ in 0..1 + rng.below(16) {
                if bytes.is_empty() {
                    break;
                }
                let i = rng.below(bytes.len());
                bytes[i] ^= 1 << rng.below(8);
            }
        }
        3 => {
            let i = rng.below(bytes.len() + 1);
            let junk: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
            bytes.splice(i..i, junk);
        }
        4 if bytes.len() > 16 => {
            // Lie in the GLB header or chunk lengths.
            let at = [8, 12, 16][rng.below(3)];
            let v = INTERESTING[rng.below(INTERESTING.len())] as u32;
            if bytes.len() >= at + 4 {
                bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
        _ => {}
    }
    bytes
}

fn limits() -> LoadOptions {
    LoadOptions {
        limits: LoadLimits {
            max_vertices: 1 << 20,
            max_triangles: 1 << 20,
            max_texture_side: 2048,
            max_total_bytes: 256 << 20,
            max_nodes: 1 << 16,
        },
    }
}

/// Output invariants of a successful load.
fn check(a: &Artefact) -> Result<(), String> {
    for (k, p) in a.primitives.iter().enumerate() {
        let n = p.positions.len();
        if p.indices.len() % 3 != 0 || p.indices.iter().any(|&i| i as usize >= n) {
            return Err(format!("primitive {k}: bad index"));
        }
        if p.normals.len() != n || p.normals.iter().any(|v| !v.is_finite()) {
            return Err(format!("primitive {k}: bad normals"));
        }
        if p.positions.iter().any(|v| !v.is_finite()) {
            return Err(format!("primitive {k}: non-finite position"));
        }
        if p.uv0
            .as_ref()
            .is_some_and(|u| u.len() != n || u.iter().any(|v| !v.is_finite()))
        {
            return Err(format!("primitive {k}: bad uv0"));
        }
        if p.tangents
            .as_ref()
            .is_some_and(|t| t.len() != n || t.iter().any(|v| !v.is_finite()))
        {
            return Err(format!("primitive {k}: bad tangents"));
        }
        if p.material >= a.materials.len() {
            return Err(format!("primitive {k}: material out of range"));
        }
    }
    for m in &a.materials {
        if m.texture_slots()
            .iter()
            .any(|(_, t)| t.texture >= a.textures.len())
        {
            return Err("texture reference out of range".into());
        }
        if !(m.base_color_factor.is_finite() && m.emissive_factor.is_finite()) {
            return Err("non-finite material factor".into());
        }
    }
    if !(a.bounds.min.is_finite() && a.bounds.max.is_finite()) {
        return Err("non-finite bounds".into());
    }
    Ok(())
}

struct Stats {
    cases: u64,
    loaded: u64,
    failed_cleanly: u64,
    slowest: Duration,
}

/// Runs mutated cases until `done(cases, elapsed)`; every case must finish within `watchdog`.
fn run(seeds: Vec<Seed>, seed: u64, watchdog: Duration, done: fn(u64, Duration) -> bool) -> Stats {
    let (tx, rx) = mpsc::channel::<(u64, String)>();
    let (result_tx, result_rx) = mpsc::channel::<Result<Stats, String>>();
    std::thread::spawn(move || {
        let mut rng = Rng::new(seed);
        let start = Instant::now();
        let mut stats = Stats {
            cases: 0,
            loaded: 0,
            failed_cleanly: 0,
            slowest: Duration::ZERO,
        };
        let options = limits();
        while !done(stats.cases, start.elapsed()) {
            let s = &seeds[rng.below(seeds.len())];
            let bytes = mutate(s, &mut rng);
            let label = format!(
                "case {} from '{}' ({} bytes)",
                stats.cases,
                s.name,
                bytes.len()
            );
            let _ = tx.send((stats.cases, label.clone()));
            let t0 = Instant::now();
            let result = std::panic::catch_unwind(|| match &s.folder {
                Some(f) => Artefact::from_bytes_in(&bytes, f, &options),
                None => Artefact::from_glb_bytes(&bytes, &options),
            });
            stats.slowest = stats.slowest.max(t0.elapsed());
            match result {
                Err(_) => {
                    let path = std::env::temp_dir()
                        .join(format!("parallax-fuzz-{seed}-{}.bin", stats.cases));
                    let _ = std::fs::write(&path, &bytes);
                    let _ = result_tx.send(Err(format!(
                        "{label}: the loader panicked; input saved to {}",
                        path.display()
                    )));
                    return;
                }
                Ok(Ok(a)) => {
                    if let Err(why) = check(&a) {
                        let _ = result_tx.send(Err(format!("{label}: loaded, but {why}")));
                        return;
                    }
                    stats.loaded += 1;
                }
                Ok(Err(e)) => {
                    if e.to_string().is_empty() {
                        let _ = result_tx.send(Err(format!("{label}: empty error message")));
                        return;
                    }
                    stats.failed_cleanly += 1;
                }
            }
            stats.cases += 1;
        }
        let _ = result_tx.send(Ok(stats));
    });
    let mut current = String::from("startup");
    loop {
        if let Ok(r) = result_rx.try_recv() {
            match r {
                Ok(stats) => return stats,
                Err(msg) => panic!("{msg}"),
            }
        }
        match rx.recv_timeout(watchdog) {
            Ok((_, label)) => current = label,
            Err(mpsc::RecvTimeoutError::Disconnected) => match result_rx.recv() {
                Ok(Ok(stats)) => return stats,
                Ok(Err(msg)) => panic!("{msg}"),
                Err(_) => panic!("fuzz worker died during {current}"),
            },
            Err(mpsc::RecvTimeoutError::Timeout) => {
                panic!("{current} did not finish within {watchdog:?}: the loader hangs")
            }
        }
    }
}

#[test]
fn mutated_assets_never_panic_or_hang_ci_batch() {
    // Fixed seed and count: deterministic, a few seconds.
    let stats = run(
        seeds(true, 64 * 1024),
        0x5EED,
        Duration::from_secs(60),
        |n, _| n >= 3000,
    );
    eprintln!(
        "fuzz CI batch: {} cases, {} loaded, {} clean errors, slowest {:?}",
        stats.cases, stats.loaded, stats.failed_cleanly, stats.slowest
    );
    // Both outcomes must occur, or the mutations are not exercising the loader.
    assert!(stats.loaded > 0 && stats.failed_cleanly > 0);
}

#[test]
#[ignore = "long fuzz run: PARALLAX_FUZZ_SECS (default 180) with --release"]
fn mutated_assets_never_panic_or_hang_long_run() {
    let seed = std::env::var("PARALLAX_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0xC0FFEE);
    let stats = run(
        seeds(true, 4 << 20),
        seed,
        Duration::from_secs(60),
        |_, t| {
            let secs = std::env::var("PARALLAX_FUZZ_SECS")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(180);
            t >= Duration::from_secs(secs)
        },
    );
    eprintln!(
        "fuzz long run (seed {seed}): {} cases, {} loaded, {} clean errors, slowest {:?}",
        stats.cases, stats.loaded, stats.failed_cleanly, stats.slowest
    );
    assert!(stats.cases > 0);
}
