//! The C# bindings (`bindings/csharp/`), the Unity package (`bindings/unity/`) and the C# host
//! example (`examples/csharp/`).
//!
//! - The P/Invoke declarations are hand-written; this test parses `include/parallax.h` and the C#
//!   files and fails when an exported `plx_` function (test hooks aside) has no `DllImport`, when
//!   a C# import names no C function, when a parameter count or type differs, or when a struct,
//!   enum or callback type differs in its fields (count, order, name, type, array length).
//! - The Unity package's `Runtime/` holds byte-identical copies of the binding files
//!   (`PARALLAX_BLESS_CSHARP=1 cargo test --test csharp` copies them there).
//! - With Mono (`mcs`, `mono`; `.ci/run` installs them), the bindings and the example are compiled
//!   with warnings as errors and run against the `libparallax.so` this `cargo test` built, on a
//!   synthetic scene from the reference path tracer: the composite's pixels, the struct sizes as
//!   marshalled by Mono, and the exceptions raised for failures are checked. The README's
//!   "Use from C#" example is compiled and run the same way, and the Unity component is compiled
//!   against a stand-in for the few UnityEngine types it uses, and run.
//!
//! Missing `mcs`/`mono` fails the test (with how to install them); it never passes silently.

mod hosts_common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hosts_common::{library_dir, root, synthetic, values};

// ---- parsing C and C# declarations ----------------------------------------------------------

/// A C or C# type as the checks compare them: the base name and the pointer depth (C), or the
/// type as written with its modifier (C#).
#[derive(Debug, Clone, PartialEq)]
struct Param {
    /// C: the type without `const`/`struct`/`enum` and stars; C#: the type as written.
    ty: String,
    /// C: number of `*`; C#: 0.
    depth: usize,
    /// C#: `ref`, `out` or "".
    modifier: String,
    name: String,
    /// C arrays in structs (`float x[3]`), C# `SizeConst`.
    array: Option<usize>,
}

#[derive(Debug, Default)]
struct Api {
    /// Function name → every declaration's parameters (C: one; C#: one per overload), return type.
    functions: HashMap<String, Vec<(Vec<Param>, Param)>>,
    structs: HashMap<String, Vec<Param>>,
    enums: HashMap<String, Vec<(String, i64)>>,
    /// Callback types: name → (parameters, return type).
    callbacks: HashMap<String, (Vec<Param>, Param)>,
}

/// Drops `/* */` and `//` comments.
fn strip_line_comments(text: &str) -> String {
    let mut text = text.to_string();
    while let Some(start) = text.find("/*") {
        let end = start + text[start..].find("*/").expect("unterminated comment") + 2;
        text.replace_range(start..end, " ");
    }
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Drops preprocessor lines and what C++-only or test-hook conditionals hold.
fn strip_c_preprocessor(text: &str) -> String {
    let mut skipping: Vec<bool> = Vec::new();
    let mut out = String::new();
    for line in text.lines() {
        let t = line.trim_start();
        if let Some(directive) = t.strip_prefix('#') {
            let d = directive.trim_start();
            if d.starts_with("ifndef") {
                skipping.push(false);
            } else if d.starts_with("if") {
                skipping.push(d.contains("__cplusplus") || d.contains("PLX_TEST_HOOKS"));
            } else if d.starts_with("endif") {
                skipping.pop();
            }
            continue;
        }
        if skipping.iter().any(|s| *s) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Splits at `sep` outside (), [], {} and <>.
fn split_top(text: &str, sep: char) -> Vec<String> {
    let mut parts = Vec::new();
    let mut depth = 0i32;
    let mut current = String::new();
    for c in text.chars() {
        match c {
            '(' | '[' | '{' | '<' => depth += 1,
            ')' | ']' | '}' | '>' => depth -= 1,
            _ => {}
        }
        if c == sep && depth == 0 {
            parts.push(std::mem::take(&mut current));
        } else {
            current.push(c);
        }
    }
    parts.push(current);
    parts
        .into_iter()
        .map(|p| p.trim().to_string())
        .filter(|p| !p.is_empty())
        .collect()
}

/// The index just past the bracket matching the one at `open`.
fn matching(text: &str, open: usize) -> usize {
    let bytes = text.as_bytes();
    let (o, c) = (bytes[open], if bytes[open] == b'(' { b')' } else { b'}' });
    let mut depth = 0;
    for (i, b) in bytes.iter().enumerate().skip(open) {
        if *b == o {
            depth += 1;
        } else if *b == c {
            depth -= 1;
            if depth == 0 {
                return i + 1;
            }
        }
    }
    panic!("unbalanced {} at {open}", o as char);
}

fn words(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `const struct plx_scene *scene` → Param { ty: plx_scene, depth: 1, name: scene }.
fn c_decl(decl: &str) -> Param {
    let decl = words(decl);
    // A function-pointer field `RET (*name)(PARAMS)`: a pointer (IntPtr in C#).
    if let Some(star) = decl.find("(*") {
        let end = star + decl[star..].find(')').expect("function pointer name");
        return Param {
            ty: "fn".into(),
            depth: 1,
            modifier: String::new(),
            name: decl[star + 2..end].trim().to_string(),
            array: None,
        };
    }
    let mut array = None;
    let mut decl = decl.as_str();
    if let Some(i) = decl.find('[') {
        array = Some(
            decl[i + 1..decl.len() - 1]
                .trim()
                .parse()
                .expect("array length"),
        );
        decl = &decl[..i];
    }
    let depth = decl.matches('*').count();
    let spaced = decl.replace('*', " ");
    let toks: Vec<&str> = spaced
        .split_whitespace()
        .filter(|t| !matches!(*t, "const" | "struct" | "enum"))
        .collect();
    let (ty, name) = match toks.as_slice() {
        [ty] => (ty.to_string(), String::new()),
        [ty, name] => (ty.to_string(), name.to_string()),
        _ => panic!("cannot read C declaration {decl:?}"),
    };
    Param {
        ty,
        depth,
        modifier: String::new(),
        name,
        array,
    }
}

fn parse_header(text: &str) -> Api {
    let text = strip_c_preprocessor(&strip_line_comments(text));
    let mut api = Api::default();
    // Declarations end at `;` outside braces.
    for decl in split_top(&text, ';') {
        let decl = words(&decl);
        if let Some(open) = decl.find('{') {
            let head = &decl[..open];
            let close = matching(&decl, open);
            let body = &decl[open + 1..close - 1];
            // Only the C API's own types (not, say, a host's interface struct).
            let Some(name) = head.split_whitespace().find(|w| w.starts_with("plx_")) else {
                continue;
            };
            let name = name.to_string();
            if head.contains("enum") {
                let mut items = Vec::new();
                for item in split_top(body, ',') {
                    let (k, v) = item.split_once('=').expect("enum item with a value");
                    items.push((k.trim().to_string(), v.trim().parse().expect("enum value")));
                }
                api.enums.insert(name, items);
            } else if head.contains("struct") {
                let fields = split_top(body, ';').iter().map(|f| c_decl(f)).collect();
                api.structs.insert(name, fields);
            }
        } else if decl.starts_with("typedef") && decl.contains("(*") {
            // typedef RET (*NAME)(PARAMS)
            let star = decl.find("(*").unwrap();
            let name_end = star + decl[star..].find(')').unwrap();
            let name = decl[star + 2..name_end].trim().to_string();
            if !name.starts_with("plx_") {
                continue;
            }
            let ret = c_decl(decl["typedef".len()..star].trim());
            let params_open = name_end + decl[name_end..].find('(').unwrap();
            let params = &decl[params_open + 1..matching(&decl, params_open) - 1];
            api.callbacks.insert(name, (c_params(params), ret));
        } else if let Some(open) = decl.find('(') {
            let before = decl[..open].trim();
            let Some(name) = before.rsplit([' ', '*']).next() else {
                continue;
            };
            // Every function, the host entry points too (`GetRenderEventFunc`): C# may import
            // those, and each import must name a function of the header.
            if name.is_empty() || !name.chars().all(|c| c.is_alphanumeric() || c == '_') {
                continue;
            }
            let ret = c_decl(before[..before.len() - name.len()].trim());
            let params = &decl[open + 1..matching(&decl, open) - 1];
            api.functions
                .entry(name.to_string())
                .or_default()
                .push((c_params(params), ret));
        }
    }
    api
}

fn c_params(params: &str) -> Vec<Param> {
    if params.trim() == "void" {
        return Vec::new();
    }
    split_top(params, ',').iter().map(|p| c_decl(p)).collect()
}

/// Removes leading `[...]` attributes; returns the rest and the attributes' text.
fn strip_attributes(text: &str) -> (String, String) {
    let mut rest = text.trim();
    let mut attrs = String::new();
    while rest.starts_with('[') {
        let bytes = rest.as_bytes();
        let mut depth = 0;
        let mut end = 0;
        for (i, b) in bytes.iter().enumerate() {
            match b {
                b'[' => depth += 1,
                b']' => {
                    depth -= 1;
                    if depth == 0 {
                        end = i + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        attrs.push_str(&rest[..end]);
        rest = rest[end..].trim_start();
    }
    (rest.to_string(), attrs)
}

fn size_const(attrs: &str) -> Option<usize> {
    let i = attrs.find("SizeConst")?;
    let digits: String = attrs[i..]
        .chars()
        .skip_while(|c| !c.is_ascii_digit())
        .take_while(|c| c.is_ascii_digit())
        .collect();
    digits.parse().ok()
}

/// `[Out] float[] localMin` → Param { ty: "float[]", modifier: "", name: "localMin" }.
fn cs_param(text: &str) -> Param {
    let (rest, _) = strip_attributes(text);
    let mut toks: Vec<&str> = rest.split_whitespace().collect();
    let modifier = match toks.first() {
        Some(m @ (&"ref" | &"out" | &"in")) => {
            let m = m.to_string();
            toks.remove(0);
            m
        }
        _ => String::new(),
    };
    assert!(toks.len() == 2, "cannot read C# parameter {text:?}");
    Param {
        ty: toks[0].to_string(),
        depth: 0,
        modifier,
        name: toks[1].to_string(),
        array: None,
    }
}

fn cs_params(params: &str) -> Vec<Param> {
    split_top(params, ',').iter().map(|p| cs_param(p)).collect()
}

fn parse_csharp(text: &str) -> Api {
    let text: String = strip_line_comments(text)
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n");
    let mut api = Api::default();
    // DllImports.
    let mut from = 0;
    while let Some(i) = text[from..].find("static extern ") {
        let start = from + i;
        let attr_at = text[..start]
            .rfind("[DllImport(")
            .expect("extern without DllImport");
        let attr = &text[attr_at..start];
        assert!(
            attr.contains("CallingConvention.Cdecl") && attr.contains("Library"),
            "DllImport without Library and Cdecl: {attr}"
        );
        let decl = words(&text[start + "static extern ".len()..]);
        let open = decl.find('(').unwrap();
        let (ret, name) = decl[..open]
            .trim()
            .split_once(' ')
            .expect("return type and name");
        let params = &decl[open + 1..matching(&decl, open) - 1];
        let ret = Param {
            ty: ret.to_string(),
            depth: 0,
            modifier: String::new(),
            name: String::new(),
            array: None,
        };
        api.functions
            .entry(name.trim().to_string())
            .or_default()
            .push((cs_params(params), ret));
        from = start + 1;
    }
    // Delegates.
    from = 0;
    while let Some(i) = text[from..].find("delegate ") {
        let start = from + i + "delegate ".len();
        let decl = words(&text[start..start + text[start..].find(';').unwrap()]);
        let open = decl.find('(').unwrap();
        let (ret, name) = decl[..open].trim().split_once(' ').unwrap();
        let params = &decl[open + 1..matching(&decl, open) - 1];
        let ret = Param {
            ty: ret.to_string(),
            depth: 0,
            modifier: String::new(),
            name: String::new(),
            array: None,
        };
        api.callbacks
            .insert(name.to_string(), (cs_params(params), ret));
        from = start;
    }
    // Structs and enums named Plx*.
    for keyword in ["struct ", "enum "] {
        from = 0;
        while let Some(i) = text[from..].find(keyword) {
            let start = from + i + keyword.len();
            from = start;
            let name: String = text[start..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.starts_with("Plx") {
                continue;
            }
            let open = start + text[start..].find('{').unwrap();
            let close = matching(&text, open);
            let body = &text[open + 1..close - 1];
            if keyword == "enum " {
                let items = split_top(body, ',')
                    .iter()
                    .map(|item| {
                        let (k, v) = item.split_once('=').expect("C# enum item with a value");
                        (k.trim().to_string(), v.trim().parse().expect("enum value"))
                    })
                    .collect();
                api.enums.insert(name, items);
            } else {
                api.structs.insert(name, cs_fields(body));
            }
        }
    }
    api
}

/// The instance fields of a C# struct body, in order (methods and their bodies skipped).
fn cs_fields(body: &str) -> Vec<Param> {
    let mut fields = Vec::new();
    let mut statement = String::new();
    let bytes = body.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'{' => {
                i = matching(body, i);
                statement.clear();
                continue;
            }
            b';' => {
                let (rest, attrs) = strip_attributes(&statement);
                let toks: Vec<&str> = rest.split_whitespace().collect();
                if !rest.contains('(')
                    && toks.first() == Some(&"public")
                    && !toks.contains(&"static")
                    && !toks.contains(&"const")
                {
                    assert!(toks.len() == 3, "cannot read C# field {rest:?}");
                    fields.push(Param {
                        ty: toks[1].to_string(),
                        depth: 0,
                        modifier: String::new(),
                        name: toks[2].to_string(),
                        array: size_const(&attrs),
                    });
                }
                statement.clear();
            }
            b => statement.push(b as char),
        }
        i += 1;
    }
    fields
}

// ---- the mapping between the two ------------------------------------------------------------

/// `plx_context_options` → `PlxContextOptions`; `max_image_pixels` → `MaxImagePixels`.
fn pascal(snake: &str) -> String {
    snake
        .split('_')
        .map(|w| {
            let mut c = w.chars();
            match c.next() {
                Some(f) => f.to_uppercase().collect::<String>() + c.as_str(),
                None => String::new(),
            }
        })
        .collect()
}

fn scalar(c: &str) -> Option<&'static str> {
    Some(match c {
        "uint32_t" => "uint",
        "int32_t" => "int",
        "uint64_t" => "ulong",
        "size_t" => "UIntPtr",
        "float" => "float",
        "double" => "double",
        "uint8_t" | "char" => "byte",
        "plx_status" => "PlxStatus",
        "void" => "void",
        _ => return None,
    })
}

fn handle(c: &str) -> Option<&'static str> {
    match c {
        "plx_scene" => Some("SceneHandle"),
        "plx_context" => Some("ContextHandle"),
        _ => None,
    }
}

/// Whether C# parameter `cs` can stand for C parameter `c`; the reason when not.
fn compatible(c: &Param, cs: &Param, api: &Api) -> Result<(), String> {
    let element = |base: &str| -> Option<String> {
        scalar(base)
            .map(str::to_string)
            .or_else(|| api.structs.contains_key(base).then(|| pascal(base)))
    };
    let ok = match c.depth {
        0 => {
            cs.modifier.is_empty()
                && if api.callbacks.contains_key(&c.ty) {
                    cs.ty == pascal(&c.ty)
                } else {
                    scalar(&c.ty) == Some(cs.ty.as_str())
                }
        }
        1 => {
            (cs.modifier.is_empty() && cs.ty == "IntPtr")
                || (cs.modifier.is_empty() && handle(&c.ty) == Some(cs.ty.as_str()))
                || (handle(&c.ty).is_none()
                    && c.ty != "void"
                    && match element(&c.ty) {
                        Some(e) => {
                            ((cs.modifier == "ref" || cs.modifier == "out") && cs.ty == e)
                                || (cs.modifier.is_empty() && cs.ty == format!("{e}[]"))
                        }
                        None => false,
                    })
        }
        2 => cs.modifier == "out" && (cs.ty == "IntPtr" || handle(&c.ty) == Some(cs.ty.as_str())),
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "C `{}{} {}` vs C# `{} {} {}`",
            c.ty,
            "*".repeat(c.depth),
            c.name,
            cs.modifier,
            cs.ty,
            cs.name
        ))
    }
}

fn compatible_return(c: &Param, cs: &Param, api: &Api) -> bool {
    match c.depth {
        // A returned function pointer (a callback type) is an IntPtr.
        0 if api.callbacks.contains_key(&c.ty) => cs.ty == "IntPtr",
        0 => scalar(&c.ty) == Some(cs.ty.as_str()),
        _ => cs.ty == "IntPtr",
    }
}

fn compatible_field(c: &Param, cs: &Param) -> bool {
    if c.name.is_empty() || pascal(&c.name) != cs.name {
        return false;
    }
    match (c.depth, c.array) {
        (0, None) => scalar(&c.ty) == Some(cs.ty.as_str()) && cs.array.is_none(),
        (0, Some(n)) => {
            scalar(&c.ty).map(|s| format!("{s}[]")) == Some(cs.ty.clone()) && cs.array == Some(n)
        }
        _ => cs.ty == "IntPtr" && cs.array.is_none(),
    }
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn binding_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("bindings/csharp"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "cs"))
        .collect();
    files.sort();
    files
}

fn csharp_api() -> Api {
    let text: String = binding_files().iter().map(|p| read(p) + "\n").collect();
    parse_csharp(&text)
}

fn header_api() -> Api {
    parse_header(&read(&root().join("include/parallax.h")))
}

/// What differs between the header's declarations `c` and the C# ones `cs`, one line each.
fn drift(c: &Api, cs: &Api) -> Vec<String> {
    let mut problems = Vec::new();
    for (name, decls) in &c.functions {
        let (c_params, c_ret) = &decls[0];
        let Some(overloads) = cs.functions.get(name) else {
            // Every plx_ function; host entry points (Unity's UnityPluginLoad …) only when imported.
            if name.starts_with("plx_") {
                problems.push(format!("{name}: no DllImport in bindings/csharp"));
            }
            continue;
        };
        for (cs_params, cs_ret) in overloads {
            if cs_params.len() != c_params.len() {
                problems.push(format!(
                    "{name}: {} parameters in C, {} in C#",
                    c_params.len(),
                    cs_params.len()
                ));
                continue;
            }
            if !compatible_return(c_ret, cs_ret, c) {
                problems.push(format!(
                    "{name}: returns {c_ret:?} in C, {} in C#",
                    cs_ret.ty
                ));
            }
            for (a, b) in c_params.iter().zip(cs_params) {
                if let Err(e) = compatible(a, b, c) {
                    problems.push(format!("{name}: {e}"));
                }
            }
        }
    }
    for name in cs.functions.keys() {
        if !c.functions.contains_key(name) {
            problems.push(format!(
                "{name}: imported in C# but not in include/parallax.h"
            ));
        }
    }
    for (name, fields) in &c.structs {
        let Some(cs_fields) = cs.structs.get(&pascal(name)) else {
            problems.push(format!("struct {name}: no {} in C#", pascal(name)));
            continue;
        };
        if cs_fields.len() != fields.len()
            || !fields
                .iter()
                .zip(cs_fields)
                .all(|(a, b)| compatible_field(a, b))
        {
            problems.push(format!(
                "struct {name}: C fields {:?} vs C# {:?}",
                fields
                    .iter()
                    .map(|f| format!("{}{} {}{:?}", f.ty, "*".repeat(f.depth), f.name, f.array))
                    .collect::<Vec<_>>(),
                cs_fields
                    .iter()
                    .map(|f| format!("{} {}{:?}", f.ty, f.name, f.array))
                    .collect::<Vec<_>>()
            ));
        }
    }
    let c_struct_names: Vec<String> = c.structs.keys().map(|n| pascal(n)).collect();
    for name in cs.structs.keys() {
        if !c_struct_names.contains(name) {
            problems.push(format!("struct {name}: in C# but not in the header"));
        }
    }
    for (name, items) in &c.enums {
        let prefix = format!("{}_", name.to_uppercase());
        let expected: Vec<(String, i64)> = items
            .iter()
            .map(|(k, v)| {
                let short = k
                    .strip_prefix(&prefix)
                    .unwrap_or_else(|| panic!("{k} in {name}"));
                (pascal(&short.to_lowercase()), *v)
            })
            .collect();
        match cs.enums.get(&pascal(name)) {
            Some(cs_items) if *cs_items == expected => {}
            other => problems.push(format!("enum {name}: C {expected:?}, C# {other:?}")),
        }
    }
    for (name, (params, ret)) in &c.callbacks {
        match cs.callbacks.get(&pascal(name)) {
            None => problems.push(format!("callback {name}: no delegate {}", pascal(name))),
            Some((cs_params, cs_ret)) => {
                if cs_params.len() != params.len() || !compatible_return(ret, cs_ret, c) {
                    problems.push(format!("callback {name}: signature differs"));
                }
                for (a, b) in params.iter().zip(cs_params) {
                    if let Err(e) = compatible(a, b, c) {
                        problems.push(format!("callback {name}: {e}"));
                    }
                }
            }
        }
    }
    problems.sort();
    problems
}

#[test]
fn every_exported_function_struct_enum_and_callback_has_its_csharp_twin() {
    let (c, cs) = (header_api(), csharp_api());
    // The parser reads what the header holds (a sanity floor, so a broken parser cannot pass).
    assert!(c.functions.len() >= 50, "{:?}", c.functions.keys());
    assert!(c.structs.len() >= 13 && c.enums.len() >= 9 && c.callbacks.len() >= 2);
    assert!(!c.functions.contains_key("plx_test_panic"));
    assert!(c.functions.contains_key("plx_scene_photo_size"));
    let problems = drift(&c, &cs);
    assert!(
        problems.is_empty(),
        "bindings/csharp has drifted from include/parallax.h:\n  {}",
        problems.join("\n  ")
    );
}

#[test]
fn the_drift_check_reports_each_kind_of_change_on_either_side() {
    let header = read(&root().join("include/parallax.h"));
    let csharp: String = binding_files().iter().map(|p| read(p) + "\n").collect();
    let (c, cs) = (parse_header(&header), parse_csharp(&csharp));
    assert_eq!(drift(&c, &cs), Vec::<String>::new());
    let expect = |c: &Api, cs: &Api, needle: &str| {
        let problems = drift(c, cs);
        assert!(
            problems.iter().any(|p| p.contains(needle)),
            "no {needle:?} in {problems:?}"
        );
    };
    let cs_with = |from: &str, to: &str| {
        assert!(csharp.contains(from), "{from:?} not in the C# files");
        parse_csharp(&csharp.replace(from, to))
    };
    let c_with = |from: &str, to: &str| {
        assert!(header.contains(from), "{from:?} not in the header");
        parse_header(&header.replace(from, to))
    };
    // C# side: a missing import, a lost parameter, a wrong type, swapped fields, an enum value.
    let up = "public static extern PlxStatus plx_scene_up(";
    expect(
        &c,
        &cs_with(up, "public static extern PlxStatus plx_scene_upp("),
        "plx_scene_up: no DllImport",
    );
    expect(
        &c,
        &cs_with(up, "public static extern PlxStatus plx_scene_upp("),
        "plx_scene_upp: imported in C# but not",
    );
    let clip = "plx_scene_set_clip(SceneHandle scene, float near, float far)";
    expect(
        &c,
        &cs_with(clip, "plx_scene_set_clip(SceneHandle scene, float near)"),
        "plx_scene_set_clip: 3 parameters in C, 2 in C#",
    );
    expect(
        &c,
        &cs_with(
            clip,
            "plx_scene_set_clip(SceneHandle scene, double near, float far)",
        ),
        "plx_scene_set_clip: C `float near`",
    );
    expect(
        &c,
        &cs_with(
            "public float Fx;\n        public float Fy;",
            "public float Fy;\n        public float Fx;",
        ),
        "struct plx_camera",
    );
    expect(
        &c,
        &cs_with("Cancelled = 12,", "Cancelled = 13,"),
        "enum plx_status",
    );
    expect(&c, &cs_with("[MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]\n        public float[] Position;", "[MarshalAs(UnmanagedType.ByValArray, SizeConst = 4)]\n        public float[] Position;"), "struct plx_light");
    // Header side: a new function, a new parameter, a new field, a new enum value.
    let status_str = "const char *plx_status_str(uint32_t status);";
    expect(
        &c_with(
            status_str,
            &format!("{status_str}\nenum plx_status plx_scene_new_thing(struct plx_scene *scene);"),
        ),
        &cs,
        "plx_scene_new_thing: no DllImport",
    );
    expect(&c_with("enum plx_status plx_scene_set_clip(struct plx_scene *scene, float near, float far);", "enum plx_status plx_scene_set_clip(struct plx_scene *scene, float near, float far, uint32_t flags);"), &cs, "plx_scene_set_clip: 4 parameters in C, 3 in C#");
    expect(
        &c_with(
            "  float cy;\n} plx_camera;",
            "  float cy;\n  float skew;\n} plx_camera;",
        ),
        &cs,
        "struct plx_camera",
    );
    expect(
        &c_with(
            "  PLX_STATUS_CANCELLED = 12,\n",
            "  PLX_STATUS_CANCELLED = 12,\n  PLX_STATUS_BUSY = 13,\n",
        ),
        &cs,
        "enum plx_status",
    );
    // And the parameter rules: a pointer is never a plain value.
    let float_ptr = c_decl("float *out");
    assert!(compatible(
        &c_decl("struct plx_scene *scene"),
        &cs_param("SceneHandle scene"),
        &c
    )
    .is_ok());
    assert!(compatible(&float_ptr, &cs_param("float out"), &c).is_err());
    assert!(compatible(&float_ptr, &cs_param("[Out] float[] out"), &c).is_ok());
    assert!(compatible(&float_ptr, &cs_param("out float out"), &c).is_ok());
    assert!(compatible(&float_ptr, &cs_param("out double out"), &c).is_err());
}

#[test]
fn the_unity_package_holds_the_same_bindings_and_the_crate_version() {
    let unity = root().join("bindings/unity");
    let bless = std::env::var_os("PARALLAX_BLESS_CSHARP").is_some();
    for file in binding_files() {
        let copy = unity.join("Runtime").join(file.file_name().unwrap());
        let source = read(&file);
        if bless {
            std::fs::write(&copy, &source).unwrap();
        }
        assert!(
            copy.exists() && read(&copy) == source,
            "{} differs from {}: run PARALLAX_BLESS_CSHARP=1 cargo test --test csharp",
            copy.display(),
            file.display()
        );
    }
    let package: serde_json::Value =
        serde_json::from_str(&read(&unity.join("package.json"))).unwrap();
    assert_eq!(package["name"], "com.parallax.compositor");
    assert_eq!(package["version"], env!("CARGO_PKG_VERSION"));
    let asmdef: serde_json::Value =
        serde_json::from_str(&read(&unity.join("Runtime/Parallax.Runtime.asmdef"))).unwrap();
    assert_eq!(asmdef["name"], "Parallax.Runtime");
    // The iOS library name: statically linked into the player.
    let native = read(&root().join("bindings/csharp/Parallax.Native.cs"));
    assert!(native.contains("#if UNITY_IOS && !UNITY_EDITOR\n            \"__Internal\";"));
}

// ---- compiling and running with Mono ------------------------------------------------------

/// `mcs` and `mono`, or a failure saying how to install them.
fn require_mono() {
    for tool in ["mcs", "mono"] {
        let found = Command::new(tool)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
        assert!(
            found,
            "`{tool}` not found: the C# tests need Mono. Install it with \
             `apt-get install mono-mcs mono-runtime` (Debian/Ubuntu; `.ci/run` does this)"
        );
    }
}

fn mcs(args: &[&std::ffi::OsStr]) {
    let out = Command::new("mcs")
        .args(["-warnaserror+", "-nologo"])
        .args(args)
        .output()
        .expect("run mcs");
    assert!(
        out.status.success(),
        "mcs {args:?} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Compiles the bindings into `dir/Parallax.dll` (as Unity would: the same files, C# 7).
fn compile_bindings(dir: &Path) -> PathBuf {
    let dll = dir.join("Parallax.dll");
    let mut args: Vec<std::ffi::OsString> = vec!["-target:library".into(), "-langversion:7".into()];
    args.push(format!("-out:{}", dll.display()).into());
    args.extend(binding_files().into_iter().map(Into::into));
    mcs(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
    dll
}

fn compile_program(sources: &[PathBuf], references: &[&Path], exe: &Path) {
    let mut args: Vec<std::ffi::OsString> = vec!["-langversion:7".into()];
    for r in references {
        args.push(format!("-r:{}", r.display()).into());
    }
    args.push(format!("-out:{}", exe.display()).into());
    args.extend(sources.iter().map(Into::into));
    mcs(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
}

/// Runs a Mono program against the library this `cargo test` built.
fn mono<S: AsRef<std::ffi::OsStr>>(exe: &Path, args: &[S]) -> Output {
    let out = Command::new("mono")
        .arg("--debug")
        .arg(exe)
        .args(args)
        .env("LD_LIBRARY_PATH", library_dir())
        // Number parsing in the examples follows the invariant culture.
        .env("LC_ALL", "C")
        .env("LANG", "C")
        .output()
        .expect("run mono");
    assert!(
        out.status.success(),
        "{} failed ({}):\n{}\n{}",
        exe.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn number(v: &HashMap<String, String>, key: &str) -> f64 {
    v.get(key)
        .unwrap_or_else(|| panic!("no {key} printed: {v:?}"))
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e}"))
}

fn vec3(v: &HashMap<String, String>, key: &str) -> [f64; 3] {
    let p: Vec<f64> = v[key].split(',').map(|x| x.parse().unwrap()).collect();
    [p[0], p[1], p[2]]
}

/// The marshalled size Mono printed for each Plx struct equals the Rust (= C) size.
fn check_layouts(v: &HashMap<String, String>) {
    use parallax::ffi;
    use std::mem::size_of;
    #[allow(unused_mut)]
    let mut rust: HashMap<&str, usize> = [
        (
            "PlxContextOptions",
            size_of::<ffi::context::plx_context_options>(),
        ),
        ("PlxImageOut", size_of::<ffi::image_io::plx_image_out>()),
        ("PlxLight", size_of::<ffi::light::plx_light>()),
        ("PlxImage", size_of::<ffi::image::plx_image>()),
        ("PlxCamera", size_of::<ffi::mesh::plx_camera>()),
        ("PlxFloatView", size_of::<ffi::stereo::plx_float_view>()),
        ("PlxMeshOptions", size_of::<ffi::mesh::plx_mesh_options>()),
        ("PlxMeshView", size_of::<ffi::mesh::plx_mesh_view>()),
        ("PlxSurface", size_of::<ffi::query::plx_surface>()),
        ("PlxHit", size_of::<ffi::query::plx_hit>()),
        (
            "PlxRenderOptions",
            size_of::<ffi::render::plx_render_options>(),
        ),
        ("PlxCalibration", size_of::<ffi::scene::plx_calibration>()),
        (
            "PlxStereoOptions",
            size_of::<ffi::stereo::plx_stereo_options>(),
        ),
    ]
    .into_iter()
    .collect();
    #[cfg(feature = "unity")]
    {
        rust.insert("PlxUnityGuid", size_of::<ffi::unity::plx_unity_guid>());
        rust.insert(
            "PlxUnityInterfaces",
            size_of::<ffi::unity::plx_unity_interfaces>(),
        );
    }
    for name in header_api().structs.keys() {
        // The Unity plugin's types exist in Rust only with the `unity` feature.
        if name.starts_with("plx_unity_") && !cfg!(feature = "unity") {
            continue;
        }
        let name = pascal(name);
        let expected = rust
            .get(name.as_str())
            .unwrap_or_else(|| panic!("{name}: add its Rust type to check_layouts"));
        assert_eq!(
            number(v, &format!("layout.{name}")) as usize,
            *expected,
            "{name}: Mono marshals a different size than the C struct"
        );
    }
}

#[test]
fn csharp_example_renders_the_box_into_the_synthetic_scene_and_raises_typed_errors() {
    require_mono();
    let dir = tempfile::tempdir().expect("temp dir");
    let truth = synthetic(dir.path());
    let dll = compile_bindings(dir.path());
    let exe = dir.path().join("parallax_example.exe");
    compile_program(&[root().join("examples/csharp/Program.cs")], &[&dll], &exe);
    // A floor pixel of the room, below the image centre.
    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let out = mono(&exe, &truth.example_args(px, py, dir.path()));
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    println!("{stdout}");
    // PARALLAX_CSHARP_OUT=DIR keeps the raw images for a look.
    if let Some(keep) = std::env::var_os("PARALLAX_CSHARP_OUT") {
        for f in ["composite.rgba", "photo.rgba", "mask.f32"] {
            std::fs::copy(dir.path().join(f), Path::new(&keep).join(f)).unwrap();
        }
    }
    let v = values(&out.stdout);
    check_layouts(&v);
    assert_eq!(v["version"], env!("CARGO_PKG_VERSION"));
    let (w, h) = (truth.width as usize, truth.height as usize);
    assert_eq!(v["size"], format!("{w}x{h}"));

    // The reconstruction the wrapper copied out is the scene's, within the matcher's error (as
    // in tests/cpp.rs).
    let d = number(&v, "disparity_centre_px");
    let z = number(&v, "depth_centre_m");
    assert!(
        (d - truth.disparity_centre_px as f64).abs() < 1.0,
        "disparity {d}"
    );
    let z_true = truth.depth_centre_m as f64;
    assert!(
        (z - z_true).abs() < 0.4 * z_true,
        "depth {z} m, truth {z_true} m"
    );
    assert!(number(&v, "mesh_triangles") > 1000.0, "{stdout}");
    assert_eq!(v["hit"], "1");
    // The box stands on the picked floor point: its bottom centre is the placement's translation
    // (the box's base is centred at its origin), and its top 0.3 m above (its largest side, one
    // unit of its local +Y: column 1 of the column-major transform).
    let m: Vec<f64> = v["artefact_transform"]
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(m.len(), 16);
    let (t, hit) = ([m[12], m[13], m[14]], vec3(&v, "point"));
    let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
    assert!(dist(t, hit) < 0.01, "translation {t:?}, picked {hit:?}");
    let height = dist([m[4], m[5], m[6]], [0.0; 3]);
    assert!((height - 0.3).abs() < 1e-3, "box {height} m tall");
    let (lo, hi) = (
        vec3(&v, "artefact_world_min"),
        vec3(&v, "artefact_world_max"),
    );
    assert!(
        (0..3).all(|i| lo[i] <= t[i] + 1e-4 && t[i] <= hi[i] + 1e-4),
        "world box {lo:?}..{hi:?} misses the base {t:?}"
    );
    assert_eq!(number(&v, "artefact_warnings"), 1.0, "{stdout}");
    assert!(number(&v, "lights") >= 1.0, "{stdout}");
    assert_eq!(v["host_lights"], "1:0,-1,0:5");
    assert_eq!(v["report_has_render"], "1");
    assert!(number(&v, "progress_stages") >= 1.0, "{stdout}");
    assert_eq!(v["clone_without_box_is_photo"], "1");

    // The photo is the left PNG byte for byte.
    let left = parallax::image::Image::load(&truth.left, &Default::default()).unwrap();
    let bpp = left.format().bytes_per_pixel();
    assert!(bpp >= 3, "{:?}", left.format());
    let photo = std::fs::read(dir.path().join("photo.rgba")).unwrap();
    let composite = std::fs::read(dir.path().join("composite.rgba")).unwrap();
    let mask: Vec<f32> = std::fs::read(dir.path().join("mask.f32"))
        .unwrap()
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    assert_eq!(
        (photo.len(), composite.len(), mask.len()),
        (w * h * 4, w * h * 4, w * h)
    );
    for (p, l) in photo.chunks_exact(4).zip(left.as_bytes().chunks_exact(bpp)) {
        assert_eq!((&p[..3], p[3]), (&l[..3], 255));
    }

    // The box is in the composite where it was placed: covered pixels around the floor pixel,
    // and there the composite is not the photo.
    let diff = |i: usize| -> f64 {
        (0..3)
            .map(|c| (composite[4 * i + c] as f64 - photo[4 * i + c] as f64).abs())
            .sum::<f64>()
            / 3.0
    };
    let covered: Vec<usize> = (0..w * h).filter(|&i| mask[i] > 0.5).collect();
    assert!(covered.len() >= 20, "only {} pixels covered", covered.len());
    let (mut sx, mut sy) = (0.0, 0.0);
    for &i in &covered {
        sx += (i % w) as f64;
        sy += (i / w) as f64;
    }
    let (cx, cy) = (sx / covered.len() as f64, sy / covered.len() as f64);
    assert!(
        (cx - px as f64).abs() < 12.0 && (cy - py as f64).abs() < 15.0,
        "box centred at ({cx:.1}, {cy:.1}), placed at ({px}, {py})"
    );
    // Most of the box differs from the floor it covers; its sides in shade can come close to
    // the dark floor behind them.
    let changed = covered.iter().filter(|&&i| diff(i) > 8.0).count();
    assert!(
        changed * 2 >= covered.len(),
        "{changed} of {} covered pixels differ from the photo",
        covered.len()
    );
    // Far from the box (the upper third of the image: walls and ceiling) the photo is unchanged,
    // but for the light the box takes from the wall and table behind it: a few grey levels over a
    // few percent of the pixels (up to 3.7 levels over 3.6 % measured), never as much as the box.
    let far: Vec<usize> = (0..w * h / 3).collect();
    let unchanged = far
        .iter()
        .filter(|&&i| diff(i) <= 2.0 && mask[i] == 0.0)
        .count();
    let largest = far.iter().map(|&i| diff(i)).fold(0.0, f64::max);
    assert!(
        unchanged * 100 >= far.len() * 95 && largest <= 8.0,
        "{unchanged} of {} far pixels unchanged, the largest change {largest}",
        far.len()
    );

    // The rest of the API, once each through the wrapper (EveryOtherCall in the example).
    let cam: Vec<f64> = v["camera"].split(',').map(|x| x.parse().unwrap()).collect();
    assert!((cam[0] - truth.focal_px).abs() < 1e-3, "{stdout}");
    assert_eq!((cam[1], cam[2]), (w as f64 / 2.0, h as f64 / 2.0));
    assert_eq!(v["clip"], "0.25,20");
    let range: Vec<f64> = v["depth_buffer_range"]
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(
        0.0 <= range[0] && range[0] < range[1] && range[1] <= 1.0,
        "{stdout}"
    );
    assert_eq!(v["confidence_size"], format!("{w}x{h}"));
    assert_eq!(v["mesh_step2_smaller"], "1");
    assert_eq!(number(&v, "fast_disparity_size") as usize, w);
    assert!(dist(vec3(&v, "place_translation"), hit) < 0.01, "{stdout}");
    assert!(
        dist(vec3(&v, "place_on_ray_translation"), hit) < 0.01,
        "{stdout}"
    );
    assert_eq!(v["memory_artefact_world_min"], "0,-0.25,-2.5");
    assert_eq!(v["sh9_set"], "0.25,0.5,0.75");
    // A uniform grey host environment (sRGB 128) comes back on the cube as its linear value.
    let cube: Vec<&str> = v["environment_cube"].split(':').collect();
    assert!(
        cube[0].parse::<u32>().unwrap() > 0 && cube[1] == "1",
        "{stdout}"
    );
    let linear = ((128.0 / 255.0 + 0.055) / 1.055f64).powf(2.4);
    assert!(
        (cube[2].parse::<f64>().unwrap() - linear).abs() < 0.01,
        "{stdout}"
    );
    assert_eq!(v["host_depth"], "2");
    assert_eq!(v["host_depth_stereo_skipped"], "1");
    assert_eq!(v["host_camera_fx"], "20");
    assert!(v["error_pixel_cap"].starts_with("TooLarge: "), "{stdout}");

    // Failures are ParallaxExceptions carrying the status and the library's message.
    let missing = dir.path().join("missing.png");
    let e = &v["error_missing_file"];
    assert!(
        e.starts_with("Io: ") && e.contains(&*missing.to_string_lossy()),
        "{e}"
    );
    assert!(
        v["error_unknown_artefact"].starts_with("InvalidArgument: "),
        "{stdout}"
    );
    assert!(v["error_unknown_artefact"].contains("9999"), "{stdout}");
    assert!(
        v["error_bad_size"].starts_with("SizeMismatch: "),
        "{stdout}"
    );
    assert!(v["error_cancelled"].starts_with("Cancelled: "), "{stdout}");
    assert!(
        v["error_callback_threw"].starts_with("Cancelled: the progress callback threw: host bug"),
        "{stdout}"
    );
    assert!(v["error_no_pair"].starts_with("NotAvailable: "), "{stdout}");
    // Unity's render thread: the event registered from C#, run on another thread through the
    // function pointer Unity would call, renders the same composite into the pinned buffer.
    if cfg!(feature = "unity") {
        assert_eq!(v["unity_event"], "Ok:1", "{stdout}");
        assert_eq!(v["unity_event_message"], "", "{stdout}");
        assert!(number(&v, "unity_event_max_diff") <= 2.0, "{stdout}");
        assert!(
            v["unity_unregistered"].starts_with("InvalidArgument:1"),
            "{stdout}"
        );
    } else {
        assert_eq!(v["unity_plugin"], "absent", "{stdout}");
    }
    // After the cancelled calls the scene still answers.
    assert!(
        (number(&v, "disparity_after_cancel") - d).abs() < 1e-3,
        "{stdout}"
    );
    // The loader's warning (generated normals) went through the log callback.
    assert!(number(&v, "log_warnings") >= 1.0, "{stdout}");
}

/// The fenced `csharp` block under `heading` in README.md.
fn readme_block(heading: &str) -> String {
    let readme = read(&root().join("README.md"));
    let section = readme
        .split(heading)
        .nth(1)
        .unwrap_or_else(|| panic!("README.md has no {heading:?}"));
    let start = section.find("```csharp\n").expect("a ```csharp block") + "```csharp\n".len();
    let len = section[start..].find("```").unwrap();
    section[start..start + len].to_string()
}

#[test]
fn readme_csharp_example_compiles_and_writes_the_composite() {
    require_mono();
    let dir = tempfile::tempdir().expect("temp dir");
    let truth = synthetic(dir.path());
    let dll = compile_bindings(dir.path());
    let source = dir.path().join("ReadmeExample.cs");
    std::fs::write(&source, readme_block("## Use from C#")).unwrap();
    let exe = dir.path().join("readme_example.exe");
    compile_program(&[source], &[&dll], &exe);
    let out_file = dir.path().join("composite.rgba");
    mono(
        &exe,
        &[
            truth.left.as_os_str(),
            truth.right.as_os_str(),
            truth.glb.as_os_str(),
            out_file.as_os_str(),
            truth.focal_px.to_string().as_ref(),
            truth.baseline_m.to_string().as_ref(),
        ],
    );
    let rgba = std::fs::read(&out_file).unwrap();
    assert_eq!(rgba.len(), (truth.width * truth.height * 4) as usize);
}

#[test]
fn unity_compositor_fills_the_output_texture_the_right_way_up() {
    require_mono();
    let dir = tempfile::tempdir().expect("temp dir");
    let truth = synthetic(dir.path());
    let (w, h) = (truth.width as usize, truth.height as usize);
    // The pair as raw top-down RGBA8 (the driver turns it into bottom-up textures, as Unity has them).
    let rgba = |path: &Path| -> Vec<u8> {
        let image = parallax::image::Image::load(path, &Default::default()).unwrap();
        let bpp = image.format().bytes_per_pixel();
        image
            .as_bytes()
            .chunks_exact(bpp)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect()
    };
    let photo = rgba(&truth.left);
    std::fs::write(dir.path().join("left.rgba"), &photo).unwrap();
    std::fs::write(dir.path().join("right.rgba"), rgba(&truth.right)).unwrap();

    let unity_dll = dir.path().join("UnityEngine.dll");
    mcs(&[
        "-target:library".as_ref(),
        "-langversion:7".as_ref(),
        format!("-out:{}", unity_dll.display()).as_ref(),
        root().join("tests/csharp/UnityEngine.cs").as_os_str(),
    ]);
    let runtime_dll = dir.path().join("Parallax.Runtime.dll");
    // Compiled as Unity compiles it: UNITY_5_3_OR_NEWER selects AOT.MonoPInvokeCallback.
    let mut args: Vec<std::ffi::OsString> = vec![
        "-target:library".into(),
        "-langversion:7".into(),
        "-define:UNITY_5_3_OR_NEWER".into(),
        format!("-r:{}", unity_dll.display()).into(),
        format!("-out:{}", runtime_dll.display()).into(),
    ];
    let mut runtime: Vec<PathBuf> = std::fs::read_dir(root().join("bindings/unity/Runtime"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "cs"))
        .collect();
    runtime.sort();
    assert!(runtime.iter().any(|p| p.ends_with("ParallaxCompositor.cs")));
    args.extend(runtime.into_iter().map(Into::into));
    mcs(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
    let exe = dir.path().join("compositor_driver.exe");
    compile_program(
        &[root().join("tests/csharp/CompositorDriver.cs")],
        &[&unity_dll, &runtime_dll],
        &exe,
    );

    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let out_file = dir.path().join("output.rgba");
    let out = mono(
        &exe,
        &[
            dir.path().join("left.rgba").as_os_str(),
            dir.path().join("right.rgba").as_os_str(),
            w.to_string().as_ref(),
            h.to_string().as_ref(),
            truth.glb.as_os_str(),
            truth.focal_px.to_string().as_ref(),
            truth.baseline_m.to_string().as_ref(),
            px.to_string().as_ref(),
            py.to_string().as_ref(),
            out_file.as_os_str(),
        ],
    );
    let v = values(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(v["output_size"], format!("{w}x{h}"));
    assert_eq!(v["applied"], "2");
    assert_eq!(v["errors_logged"], "0", "{stderr}");
    assert_eq!(v["gravity_composed"], "1");
    assert_eq!(v["missing_model_composed"], "0");
    assert_eq!(v["errors_logged_after"], "1");
    assert!(
        stderr.contains("Io: ") && stderr.contains("missing.glb"),
        "{stderr}"
    );

    // Unity's bottom-up rows, flipped back to the photo's top-down order.
    let bottom_up = std::fs::read(&out_file).unwrap();
    assert_eq!(bottom_up.len(), w * h * 4);
    let mut composite = vec![0u8; w * h * 4];
    for y in 0..h {
        let src = (h - 1 - y) * w * 4;
        composite[y * w * 4..(y + 1) * w * 4].copy_from_slice(&bottom_up[src..src + w * 4]);
    }
    let diff = |x: usize, y: usize| -> f64 {
        let i = 4 * (y * w + x);
        (0..3)
            .map(|c| (composite[i + c] as f64 - photo[i + c] as f64).abs())
            .sum::<f64>()
            / 3.0
    };
    // The box stands on the floor pixel (top-down): the photo changed around and above it ...
    let (bx, by) = (px as usize, py as usize);
    let window: Vec<(usize, usize)> = (bx - 8..=bx + 8)
        .flat_map(|x| (by - 16..=by + 2).map(move |y| (x, y)))
        .collect();
    let near = window.iter().filter(|&&(x, y)| diff(x, y) > 8.0).count();
    assert!(
        near * 4 >= window.len(),
        "only {near} of {} pixels around the box differ from the photo",
        window.len()
    );
    // ... and not at the mirrored position, nor anywhere in the upper third (but for the few
    // grey levels of light the box takes from the wall behind it, as in the example's test).
    let upper = || (0..h / 3).flat_map(|y| (0..w).map(move |x| (x, y)));
    let unchanged = upper().filter(|&(x, y)| diff(x, y) <= 2.0).count();
    let largest = upper().map(|(x, y)| diff(x, y)).fold(0.0, f64::max);
    assert!(
        unchanged * 100 >= (h / 3) * w * 95 && largest <= 8.0,
        "{unchanged} of {} upper pixels unchanged, the largest change {largest}: rows flipped?",
        (h / 3) * w
    );
}
