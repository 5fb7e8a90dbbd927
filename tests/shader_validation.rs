//! Every shader in `shaders/`, resolved by the runtime's `shader_source`, parses and validates with
//! naga (all validation flags and capabilities), without an adapter (STYLE §5.5, after rerun's
//! `re_renderer/tests/shader_validation.rs`). All failures are collected before one assert, and the
//! test fails if it checked no file or if a file on disk is not registered.

use perfuse::sim::gpu::shaders::{SHADER_FILES, shader_source};

fn validate(name: &str) -> Result<naga::Module, String> {
    let src = shader_source(name).map_err(|e| e.to_string())?;
    let module = naga::front::wgsl::parse_str(&src).map_err(|e| e.emit_to_string(&src))?;
    let mut v = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
    v.validate(&module).map_err(|e| e.emit_to_string(&src))?;
    Ok(module)
}

#[test]
fn all_shaders_validate() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut failures = Vec::new();
    let mut checked = 0;
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .expect("shaders/ exists")
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "wgsl"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    on_disk.sort();
    for name in &on_disk {
        if !SHADER_FILES.iter().any(|(n, _)| n == name) {
            failures.push(format!("{name}.wgsl is not registered in SHADER_FILES"));
            continue;
        }
        // The embedded copy must be the file on disk (a stale build would validate old text).
        let disk = std::fs::read_to_string(dir.join(format!("{name}.wgsl"))).expect("readable");
        let embedded = SHADER_FILES.iter().find(|(n, _)| n == name).map(|(_, s)| *s).unwrap_or("");
        if disk != embedded {
            failures.push(format!("{name}.wgsl: embedded text differs from disk (rebuild)"));
        }
        match validate(name) {
            Ok(_) => checked += 1,
            Err(e) => failures.push(format!("{name}.wgsl:\n{e}")),
        }
    }
    assert!(failures.is_empty(), "{} shader(s) failed:\n{}", failures.len(), failures.join("\n\n"));
    assert!(checked >= 1, "no shader was checked");
}

/// Every entry point uses the workgroup size of its family's Rust constant.
#[test]
fn workgroup_sizes_match_rust() {
    for pass in perfuse::sim::gpu::passes::ALL_PASSES {
        let module = validate(pass.family).unwrap_or_else(|e| panic!("{e}"));
        let ep = module
            .entry_points
            .iter()
            .find(|e| e.name == pass.entry)
            .unwrap_or_else(|| panic!("entry point {} missing from {}.wgsl", pass.entry, pass.family));
        assert_eq!(ep.workgroup_size, [pass.workgroup_size, 1, 1], "{}", pass.entry);
    }
}

/// Each entry point's naga-reflected bindings are a subset of the slots its pass declares in
/// passes.rs, so a binding edit fails here rather than at pipeline creation.
#[test]
fn bindings_match_pass_table() {
    for pass in perfuse::sim::gpu::passes::ALL_PASSES {
        let module = validate(pass.family).unwrap_or_else(|e| panic!("{e}"));
        let info = {
            let mut v =
                naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
            v.validate(&module).expect("valid")
        };
        let idx = module.entry_points.iter().position(|e| e.name == pass.entry).expect("entry point");
        let ep_info = info.get_entry_point(idx);
        let declared: Vec<u32> = pass.slots.iter().map(|s| s.binding()).collect();
        for (handle, var) in module.global_variables.iter() {
            if ep_info[handle].is_empty() {
                continue;
            }
            if let Some(b) = &var.binding {
                assert_eq!(b.group, 0, "{}: group", pass.entry);
                assert!(
                    declared.contains(&b.binding),
                    "{} uses binding {} ({:?}) that passes.rs does not declare",
                    pass.entry,
                    b.binding,
                    var.name
                );
            }
        }
    }
}

/// Host structs have the size and member offsets naga computes for the WGSL struct of the same name.
#[test]
fn struct_layouts_match_wgsl() {
    use perfuse::sim::gpu::gpu_types::LAYOUTS;
    let module = validate("common").unwrap_or_else(|e| panic!("{e}"));
    let mut checked = 0;
    for (name, size, offsets) in LAYOUTS {
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no WGSL struct {name}"))
            .1;
        match &ty.inner {
            naga::TypeInner::Struct { members, span } => {
                assert_eq!(*span as usize, *size, "{name}: size");
                for (mname, off) in offsets.iter() {
                    let m = members
                        .iter()
                        .find(|m| m.name.as_deref() == Some(mname))
                        .unwrap_or_else(|| panic!("{name}.{mname} missing in WGSL"));
                    assert_eq!(m.offset as usize, *off, "{name}.{mname}: offset");
                }
                checked += 1;
            }
            other => panic!("{name} is not a struct: {other:?}"),
        }
    }
    assert!(checked >= 5);
}

/// The WGSL flag bit of a boundary particle that stands in the tissue's place is the Rust one.
#[test]
fn boundary_in_tissue_bit_matches_rust() {
    assert_eq!(u32_constant("density", "BOUNDARY_IN_TISSUE"), perfuse::sim::gpu::gpu_types::BOUNDARY_IN_TISSUE);
}

/// The cells per invocation of the scan's block passes: grid.wgsl's SCAN_CHUNK sizes the work each
/// invocation does, passes.rs's sizes the dispatch; if they disagree the scan misses cells or repeats them.
#[test]
fn scan_chunk_matches_rust() {
    assert_eq!(u32_constant("grid", "SCAN_CHUNK"), perfuse::sim::gpu::passes::SCAN_CHUNK);
}

/// The steps over which the capsule's seal walks blood back to the capsule's plane and stops it: the
/// shader's and its CPU twin's are the same numbers.
#[test]
fn capsule_seal_steps_match_rust() {
    use perfuse::sim::cpu::forces::{CAPSULE_SEAL_STEPS, CAPSULE_SEAL_STOP_STEPS};
    for (name, rust) in
        [("CAPSULE_SEAL_STEPS", CAPSULE_SEAL_STEPS), ("CAPSULE_SEAL_STOP_STEPS", CAPSULE_SEAL_STOP_STEPS)]
    {
        match literal("forces", name) {
            naga::Literal::F32(v) => assert_eq!(v, rust, "{name}"),
            other => panic!("{name} is {other:?}, not an f32 literal"),
        }
    }
}

/// The value of the u32 constant `name` of shader family `family` (a literal in the WGSL).
fn u32_constant(family: &str, name: &str) -> u32 {
    match literal(family, name) {
        naga::Literal::U32(v) => v,
        other => panic!("{name} is {other:?}, not a u32 literal"),
    }
}

/// The literal that initialises the constant `name` of shader family `family`.
fn literal(family: &str, name: &str) -> naga::Literal {
    let module = validate(family).unwrap_or_else(|e| panic!("{e}"));
    let c = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .map(|(_, c)| c.init)
        .unwrap_or_else(|| panic!("{name} in {family}.wgsl"));
    match module.global_expressions[c] {
        naga::Expression::Literal(l) => l,
        ref e => panic!("{name} is {e:?}, not a literal"),
    }
}

/// The compute shaders are built without wgpu's loop bounding (`create_shader_module_trusted` in
/// `sim::gpu`), which is sound only if none of their loops can run forever. This test pins the loops
/// that the SAFETY comment there audits: every `for` steps its variable upward by a positive amount (or
/// doubles it from 1), and the `while` and bare `loop` statements are the four listed. A new loop of
/// another shape fails here until it is audited and added.
#[test]
fn compute_loops_are_the_audited_ones() {
    let mut failures = Vec::new();
    let mut for_loops = 0;
    let mut others = Vec::new();
    for (name, text) in SHADER_FILES {
        if name.starts_with("render_") {
            continue;
        }
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("").trim();
            if let Some(head) = code.strip_prefix("for (") {
                for_loops += 1;
                let update = head.rsplit(';').next().unwrap_or("").trim().trim_end_matches('{').trim();
                let update = update.strip_suffix(')').unwrap_or(update).trim();
                let var = head.strip_prefix("var ").and_then(|h| h.split([' ', ':']).next()).unwrap_or("");
                let allowed = [
                    format!("{var}++"),
                    format!("{var} += kstep"),
                    format!("{var} = {var} + 1u"),
                    format!("{var} = {var} + 64u"),
                    format!("{var} = {var} + COMPACT_WG"),
                    format!("{var} = {var} * 2u"),
                ];
                if var.is_empty() || !allowed.contains(&update.to_string()) {
                    failures.push(format!("{name}.wgsl:{}: for loop with update `{update}`", n + 1));
                }
            } else if code.starts_with("while ") || code.starts_with("while(") || code == "loop {" {
                others.push(format!("{name}: {code}"));
            }
        }
    }
    let audited = [
        "common: while (hi - lo > 1u) {",
        "common: loop {",
        "emit: while (em.acc >= em.volume && tries < em.slot_count) {",
        "grid: loop {",
    ];
    for o in &others {
        if !audited.contains(&o.as_str()) {
            failures.push(format!("unaudited loop: {o}"));
        }
    }
    assert_eq!(others.len(), audited.len(), "loops found: {others:?}");
    assert!(for_loops > 50, "found only {for_loops} for loops: is the scan broken?");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
