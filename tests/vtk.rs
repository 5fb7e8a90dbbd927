//! VTK export (issue 8, item 4): a `.vtu` frame read back by an independent parser (quick-xml for the
//! XML, the appended block decoded by its offsets and UInt64 headers as the VTK file format describes
//! them) equals the state bit for bit; `run_headless` with `vtk` writes one `.vtu` per CSV frame and a
//! `.pvd` with their times; `perfuse replay --vtk` exports a recording (and still verifies); bad
//! `--every` values are clear errors.

mod common;

use common::scenes::{PERFUSED_BLOCK_3D, perfused_block};
use glam::Mat3;
use perfuse::output::vtk::write_frame_vtu;
use perfuse::output::{RunLength, RunOptions, run_headless};
use perfuse::replay::format::read_recording_file;
use perfuse::replay::session::{RecordedSimulation, Recorder, replay_with};
use perfuse::scenario::Scenario;
use perfuse::sim::{BackendKind, Command, Simulation, State};
use quick_xml::XmlVersion;
use quick_xml::events::Event;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command as Process;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("perfuse-vtk-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// One `<DataArray>` of a `.vtu` and its decoded bytes.
struct Array {
    ty: String,
    components: usize,
    bytes: Vec<u8>,
}

impl Array {
    fn chunks<const N: usize>(&self) -> impl Iterator<Item = [u8; N]> + '_ {
        assert_eq!(self.bytes.len() % N, 0, "array of {} has {} bytes", self.ty, self.bytes.len());
        self.bytes.chunks_exact(N).map(|c| c.try_into().expect("chunk"))
    }
    fn f32s(&self) -> Vec<f32> {
        assert_eq!(self.ty, "Float32");
        self.chunks::<4>().map(f32::from_le_bytes).collect()
    }
    fn f64s(&self) -> Vec<f64> {
        assert_eq!(self.ty, "Float64");
        self.chunks::<8>().map(f64::from_le_bytes).collect()
    }
    fn u32s(&self) -> Vec<u32> {
        assert_eq!(self.ty, "UInt32");
        self.chunks::<4>().map(u32::from_le_bytes).collect()
    }
    /// Integer array of any VTK integer type, widened.
    fn ints(&self) -> Vec<i64> {
        match self.ty.as_str() {
            "UInt8" => self.bytes.iter().map(|&b| b as i64).collect(),
            "Int32" => self.chunks::<4>().map(|c| i32::from_le_bytes(c) as i64).collect(),
            "UInt32" => self.chunks::<4>().map(|c| u32::from_le_bytes(c) as i64).collect(),
            "Int64" => self.chunks::<8>().map(i64::from_le_bytes).collect(),
            t => panic!("not an integer type: {t}"),
        }
    }
}

fn type_size(ty: &str) -> usize {
    match ty {
        "UInt8" | "Int8" => 1,
        "UInt32" | "Int32" | "Float32" => 4,
        "UInt64" | "Int64" | "Float64" => 8,
        t => panic!("unexpected VTK type {t}"),
    }
}

/// A `.vtu` read back: the root's attributes, the piece's counts and every array by `section/name`.
struct Vtu {
    root: HashMap<String, String>,
    points: usize,
    cells: usize,
    arrays: HashMap<String, Array>,
}

fn attrs(e: &quick_xml::events::BytesStart) -> HashMap<String, String> {
    e.attributes()
        .map(|a| {
            let a = a.expect("attribute");
            let key = String::from_utf8(a.key.as_ref().to_vec()).expect("utf-8 key");
            (key, a.normalized_value(XmlVersion::Explicit1_0).expect("value").into_owned())
        })
        .collect()
}

/// Parses a `.vtu` with raw appended data: the XML up to the `_` marker of `<AppendedData>` (closed
/// by hand) through quick-xml, then each array at `_ + 1 + offset` as a little-endian UInt64 byte
/// count followed by that many bytes. Checks that the arrays tile the block exactly and that the
/// document closes after it.
fn read_vtu(path: &Path) -> Vtu {
    let bytes = std::fs::read(path).expect("read vtu");
    let tag = b"<AppendedData encoding=\"raw\">";
    let at = bytes.windows(tag.len()).position(|w| w == tag).expect("raw appended data");
    let underscore = at + tag.len() + bytes[at + tag.len()..].iter().position(|&b| b == b'_').expect("`_` marker");
    assert!(bytes[at + tag.len()..underscore].iter().all(|b| b.is_ascii_whitespace()), "only blanks before `_`");
    let head =
        std::str::from_utf8(&bytes[..at + tag.len()]).expect("utf-8 xml").to_string() + "</AppendedData></VTKFile>";
    let blob = &bytes[underscore + 1..];
    let mut reader = quick_xml::Reader::from_str(&head);
    let mut stack: Vec<String> = Vec::new();
    let (mut root, mut points, mut cells) = (HashMap::new(), 0, 0);
    let mut arrays = HashMap::new();
    let mut blob_end = 0usize;
    loop {
        match reader.read_event().expect("well-formed xml") {
            Event::Eof => break,
            Event::Start(e) | Event::Empty(e) if e.name().as_ref() == b"DataArray" => {
                let a = attrs(&e);
                assert_eq!(a["format"], "appended");
                let offset: usize = a["offset"].parse().expect("offset");
                let n = u64::from_le_bytes(blob[offset..offset + 8].try_into().expect("header")) as usize;
                let data = blob[offset + 8..offset + 8 + n].to_vec();
                blob_end = blob_end.max(offset + 8 + n);
                let section = stack.last().expect("inside a section");
                if section == "FieldData" {
                    // VTK reads no tuples from a field-data array that does not give their number.
                    let tuples: usize = a["NumberOfTuples"].parse().expect("NumberOfTuples");
                    assert_eq!(tuples * type_size(&a["type"]), n, "{}", a["Name"]);
                }
                let key = format!("{section}/{}", a["Name"]);
                let components = a.get("NumberOfComponents").map_or(1, |c| c.parse().expect("components"));
                arrays.insert(key, Array { ty: a["type"].clone(), components, bytes: data });
            }
            Event::Start(e) => {
                let name = String::from_utf8(e.name().as_ref().to_vec()).expect("utf-8");
                let a = attrs(&e);
                match name.as_str() {
                    "VTKFile" => root = a,
                    "Piece" => {
                        points = a["NumberOfPoints"].parse().expect("points");
                        cells = a["NumberOfCells"].parse().expect("cells");
                    }
                    _ => {}
                }
                stack.push(name);
            }
            Event::End(_) => {
                stack.pop();
            }
            _ => {}
        }
    }
    let total: usize = arrays.values().map(|a| 8 + a.bytes.len()).sum();
    assert_eq!(total, blob_end, "the arrays tile the appended block");
    let tail = std::str::from_utf8(&blob[blob_end..]).expect("text after the block");
    assert_eq!(tail.split_whitespace().collect::<Vec<_>>(), ["</AppendedData>", "</VTKFile>"], "closing tags");
    Vtu { root, points, cells, arrays }
}

/// (timestep, file) of each `<DataSet>` of a `.pvd`.
fn read_pvd(path: &Path) -> Vec<(f64, String)> {
    let text = std::fs::read_to_string(path).expect("read pvd");
    let mut reader = quick_xml::Reader::from_str(&text);
    let mut out = Vec::new();
    let mut root_seen = false;
    loop {
        match reader.read_event().expect("well-formed pvd") {
            Event::Eof => break,
            Event::Start(e) if e.name().as_ref() == b"VTKFile" => {
                assert_eq!(attrs(&e)["type"], "Collection");
                root_seen = true;
            }
            Event::Empty(e) if e.name().as_ref() == b"DataSet" => {
                let a = attrs(&e);
                out.push((a["timestep"].parse().expect("timestep"), a["file"].clone()));
            }
            _ => {}
        }
    }
    assert!(root_seen, "a VTKFile Collection");
    out
}

/// The bits of an f32 slice, for exact comparisons that also tell ±0 and NaNs apart.
fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The perfused block after a few steps of the descending tool, with some bonds marked broken.
fn stepped_block() -> (State, perfuse::sim::params::Params) {
    let mut sim = Simulation::new(&perfused_block(), BackendKind::Cpu).expect("sim");
    sim.advance(40, f64::INFINITY).expect("advance");
    let mut st = sim.read_state().expect("state");
    // Fracture takes far longer than a test should; the export only maps bonds_initial − bonds.
    for (k, b) in st.solid_extra.bonds.iter_mut().enumerate().filter(|(k, _)| k % 7 == 3) {
        *b = b.saturating_sub(1 + (k % 3) as u32);
    }
    (st, sim.params().clone())
}

#[test]
fn vtu_frame_reads_back_bit_for_bit() {
    let (st, params) = stepped_block();
    let (nl, ns) = (st.liquid.len(), st.solid.len());
    assert!(nl > 0 && ns > 0 && !st.boundary.pos.is_empty());
    let dir = temp_dir("roundtrip");
    let path = dir.join("frame.vtu");
    let started = std::time::Instant::now();
    let size = write_frame_vtu(&path, &st, &params).expect("write");
    let write_s = started.elapsed().as_secs_f64();
    assert_eq!(size, std::fs::metadata(&path).expect("meta").len());
    let n = nl + ns;
    eprintln!(
        "{n} particles: {size} bytes, {:.1} bytes/particle, written in {:.2} ms",
        size as f64 / n as f64,
        write_s * 1e3
    );
    let v = read_vtu(&path);
    assert_eq!(v.root["type"], "UnstructuredGrid");
    assert_eq!(v.root["byte_order"], "LittleEndian");
    assert_eq!(v.root["header_type"], "UInt64");
    assert_eq!((v.points, v.cells), (n, n), "liquid + solid, no boundary particles");

    // Points: world coordinates, exactly x_sim + origin in f64 (what the CSV frames print).
    let pts = &v.arrays["Points/Points"];
    assert_eq!(pts.components, 3);
    let want: Vec<f64> = st.liquid.pos.iter().chain(&st.solid.pos).flat_map(|p| params.to_world(*p)).collect();
    assert_eq!(pts.f64s(), want);
    assert!(params.origin.iter().any(|&o| o != 0.0), "the test scene has an origin to add");

    // Cells: one VTK_VERTEX per particle.
    assert_eq!(v.arrays["Cells/connectivity"].ints(), (0..n as i64).collect::<Vec<_>>());
    assert_eq!(v.arrays["Cells/offsets"].ints(), (1..=n as i64).collect::<Vec<_>>());
    assert!(v.arrays["Cells/types"].ints().iter().all(|&t| t == 1));

    let pd = |name: &str| &v.arrays[&format!("PointData/{name}")];
    let phase = pd("phase").ints();
    assert_eq!(phase, [vec![0; nl], vec![1; ns]].concat());
    assert_eq!(pd("id").u32s(), [st.liquid.id.clone(), st.solid.id.clone()].concat());
    assert_eq!(pd("velocity").components, 3);
    let vel: Vec<f32> = st.liquid.vel.iter().chain(&st.solid.vel).flat_map(|v| [v.x, v.y, v.z]).collect();
    assert_eq!(bits(&pd("velocity").f32s()), bits(&vel));
    for (name, l, s) in [
        ("density", &st.liquid.rho, &st.solid.rho),
        ("n_s", &st.liquid.n_s, &st.solid.n_s),
        ("n_l", &st.liquid.n_l, &st.solid.n_l),
        ("pressure", &st.liquid.p, &st.solid.p),
    ] {
        assert_eq!(bits(&pd(name).f32s()), bits(&[l.clone(), s.clone()].concat()), "{name}");
    }
    let broken: Vec<i64> = std::iter::repeat_n(0, nl)
        .chain((0..ns).map(|i| st.solid_extra.bonds_initial[i] as i64 - st.solid_extra.bonds[i] as i64))
        .collect();
    assert!(broken.iter().any(|&b| b > 0));
    assert_eq!(pd("broken_bonds").ints(), broken);

    // Stress: σ = τ(F) − nˢpˢI from the solver's own Mooney–Rivlin function, row-major.
    let stress = pd("stress");
    assert_eq!(stress.components, 9);
    let got = stress.f32s();
    assert!(got[..9 * nl].iter().all(|&x| x.to_bits() == 0), "liquid rows are +0");
    let mut max_vm = 0.0f64;
    for i in 0..ns {
        let tau = perfuse::sim::cpu::solid::mooney_rivlin_tau(st.solid_extra.def_grad[i], params.c10, params.c01);
        let sigma = tau - Mat3::IDENTITY * (st.solid.n_s[i] * st.solid.p[i]);
        let row = &got[9 * (nl + i)..9 * (nl + i + 1)];
        for r in 0..3 {
            for c in 0..3 {
                assert_eq!(row[3 * r + c].to_bits(), sigma.col(c)[r].to_bits(), "σ[{r}][{c}] of solid {i}");
            }
        }
        // von Mises from the read-back tensor in f64.
        let s: Vec<f64> = row.iter().map(|&x| x as f64).collect();
        let tr = (s[0] + s[4] + s[8]) / 3.0;
        let ss: f64 = (0..9).map(|k| if k % 4 == 0 { (s[k] - tr).powi(2) } else { s[k].powi(2) }).sum();
        let vm = (1.5 * ss).sqrt();
        let got_vm = pd("von_mises").f32s()[nl + i] as f64;
        assert!((got_vm - vm).abs() <= 1e-4 * vm.max(1e-3), "von Mises of solid {i}: {got_vm} vs {vm}");
        max_vm = max_vm.max(vm);
    }
    assert!(max_vm > 0.0, "the tool has deformed the block");
    assert!(pd("von_mises").f32s()[..nl].iter().all(|&x| x == 0.0));
    let time = v.arrays["FieldData/TimeValue"].f64s();
    assert_eq!(time, vec![st.t]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The block scene with CSV frames every millisecond.
fn block_with_frames(dt: f64) -> Scenario {
    let text = PERFUSED_BLOCK_3D
        .replace("duration: 0.01,", &format!("duration: 0.01, output: Output(frame_interval: Some({dt})),"));
    assert_ne!(text, PERFUSED_BLOCK_3D);
    Scenario::from_str_named(&text, "vtk_block.ron").expect("valid")
}

#[test]
fn run_headless_writes_a_vtu_per_frame_and_a_pvd_with_their_times() {
    let sc = block_with_frames(0.001);
    let dir = temp_dir("run");
    let opts = RunOptions {
        backend: BackendKind::Cpu,
        length: Some(RunLength::Until(0.0025)),
        out: Some(dir.clone()),
        progress: false,
        vtk: true,
        relaxed_cache: None,
        fresh_relaxation: false,
    };
    let summary = run_headless(&sc, &opts).expect("run");
    assert!(!summary.diverged);
    assert_eq!(summary.frames_written, 3, "frames at 0, 1, 2 ms: {:?}", summary.frame_times_s);
    let pvd = read_pvd(&dir.join("frames.pvd"));
    // Every CSV frame has its .vtu at the same time; the final state (between frame times) closes it.
    let mut want: Vec<(f64, String)> =
        summary.frame_times_s.iter().enumerate().map(|(k, &t)| (t, format!("frame_{k:05}.vtu"))).collect();
    assert!(dir.join("final.csv").exists());
    want.push((summary.simulated_time_s, "final.vtu".to_string()));
    assert_eq!(pvd, want);
    for (t, file) in &pvd {
        let v = read_vtu(&dir.join(file));
        assert_eq!(v.arrays["FieldData/TimeValue"].f64s(), vec![*t], "{file}");
        let csv = dir.join(file.replace(".vtu", ".csv"));
        let rows = std::fs::read_to_string(&csv).expect("csv beside the vtu").lines().count() - 1;
        assert_eq!(v.points, rows, "{file}: the same particles as {}", csv.display());
        assert_eq!(v.points, summary.particles.liquid + summary.particles.solid);
    }
    // Without the flag: no VTK files.
    let plain = temp_dir("run-plain");
    let opts = RunOptions { out: Some(plain.clone()), vtk: false, ..opts };
    run_headless(&sc, &opts).expect("run");
    assert!(std::fs::read_dir(&plain).expect("dir").all(|e| {
        let p = e.expect("entry").path();
        p.extension().is_none_or(|x| x != "vtu" && x != "pvd")
    }));
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&plain);
}

/// Records a short session on the block scene (a tool moved by commands, state hashes along the way).
fn record(path: &Path) {
    let sc = perfused_block();
    let sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let recorder = Recorder::create(path, &sc, "Cpu", "").expect("recorder");
    let mut rs = RecordedSimulation { sim, recorder: Some(recorder) };
    rs.relax().expect("relax");
    rs.apply(&Command::PlaceObject { object: 1, position: [0.0025, 0.003, 0.0052] }).expect("place");
    rs.sim.advance(20, f64::INFINITY).expect("advance");
    rs.checkpoint().expect("hash");
    rs.apply(&Command::MoveObject { object: 1, target: [0.0035, 0.003, 0.0046], speed: 0.05 }).expect("move");
    rs.sim.advance(30, f64::INFINITY).expect("advance");
    rs.checkpoint().expect("hash");
    rs.recorder.take().expect("recording").finish().expect("finish");
}

#[test]
fn replay_exports_a_vtk_series_from_the_cli() {
    let dir = temp_dir("replay");
    let rec_path = dir.join("session.pfr");
    record(&rec_path);
    let rec = read_recording_file(&rec_path).expect("readable");
    // In-process: frame stops leave the replay bit-identical (hashes verified, same final hash).
    let plain = perfuse::replay::session::replay(&rec, BackendKind::Cpu, true).expect("replay");
    let mut times = Vec::new();
    let with = replay_with(&rec, BackendKind::Cpu, true, Some(0.0005), |st, _| {
        times.push(st.t);
        Ok::<(), perfuse::replay::session::SessionError>(())
    })
    .expect("replay_with");
    assert_eq!(with.final_hash, plain.final_hash);
    assert!(with.mismatches.is_empty() && with.hashes_checked == 2);
    assert_eq!(times.first(), Some(&0.0));
    assert_eq!(times.last(), Some(&plain.t));

    let out_dir = dir.join("series");
    let out = Process::new(env!("CARGO_BIN_EXE_perfuse"))
        .args(["replay", rec_path.to_str().expect("utf-8"), "--verify", "--vtk"])
        .arg(&out_dir)
        .args(["--every", "0.0005"])
        .output()
        .expect("run perfuse");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("0 mismatches"), "{stdout}");
    let pvd = read_pvd(&out_dir.join("frames.pvd"));
    assert_eq!(pvd.iter().map(|(t, _)| *t).collect::<Vec<_>>(), times, "the CLI lists the frames replay_with shows");
    // Frame k is the first step boundary at or after k·0.5 ms; the last entry is the final state.
    let dt_max = 2e-4;
    for (k, (t, file)) in pvd.iter().enumerate().take(pvd.len() - 1) {
        let due = k as f64 * 0.0005;
        assert!(*t >= due - 1e-12 && *t < due + dt_max, "frame {k} at {t} s");
        assert_eq!(file, &format!("frame_{k:05}.vtu"));
        assert_eq!(read_vtu(&out_dir.join(file)).arrays["FieldData/TimeValue"].f64s(), vec![*t]);
    }
    assert!(pvd.len() >= 3);
    let last = read_vtu(&out_dir.join(&pvd[pvd.len() - 1].1));
    assert_eq!(last.arrays["FieldData/TimeValue"].f64s(), vec![plain.t]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_every_values_are_clear_errors() {
    let dir = temp_dir("bad-every");
    let missing = dir.join("no-such.pfr");
    let cases: [&[&str]; 5] = [
        &["--vtk", "x", "--every=-1"],
        &["--vtk", "x", "--every", "0"],
        &["--vtk", "x", "--every", "nan"],
        &["--vtk", "x", "--every", "soon"],
        &["--every", "0.01"], // --every needs --vtk
    ];
    for args in cases {
        let out = Process::new(env!("CARGO_BIN_EXE_perfuse"))
            .arg("replay")
            .arg(&missing)
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("run perfuse");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(stderr.contains("--every"), "{args:?}: the error names the flag: {stderr}");
        assert!(!dir.join("x").exists(), "{args:?}: nothing written");
    }
    // `render --every` is checked before any GPU or simulation work.
    let scene = dir.join("block.ron");
    std::fs::write(&scene, PERFUSED_BLOCK_3D).expect("scene");
    for args in [&["--every", "0", "--until", "0.01"][..], &["--every", "0.01", "--until", "0.01", "--at", "0.02"]] {
        let out = Process::new(env!("CARGO_BIN_EXE_perfuse"))
            .arg("render")
            .arg(&scene)
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("run perfuse");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && !stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(stderr.contains("--every") || stderr.contains("--until"), "{args:?}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
