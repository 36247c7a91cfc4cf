//! Work that would outgrow the machine is estimated and refused before it starts (issue 30):
//! scenes amplified by instancing or shared images, plans whose fine schemes all-gather bands,
//! bench matrices of millions of cells, runs under an address-space limit, saved frames that
//! would not fit on the disk; and a bench's running cell ends with the bench. Every run that
//! could allocate has an address-space cap (`ulimit -v`) and a deadline, so a regression fails
//! the test instead of taking the machine down.

mod common;

use common::{HANG_GUARD, capped_command, scratch, snapshot, wait_or_kill, write_gltf};

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Address space of a capped run: far less than any of the refused runs would take.
const MEMORY_CAP_KIB: u64 = 4 << 20;

/// Runs the binary in `dir` under `ulimit -v cap_kib`, killed at the hang guard.
fn capped_at(dir: &Path, cap_kib: u64, args: &[&str]) -> Output {
    wait_or_kill(capped_command(dir, cap_kib, args).spawn().unwrap(), &format!("{args:?}"))
}

/// Asserts exit 1 with exactly one line on stderr that holds every needle, no panic, and
/// nothing written in `dir`.
fn refused_at(dir: &Path, cap_kib: u64, args: &[&str], needles: &[&str]) -> String {
    let before = snapshot(dir);
    let out = capped_at(dir, cap_kib, args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: one line expected: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: expected '{needle}' in: {stderr}");
    }
    assert!(snapshot(dir) == before, "{args:?} changed {}", dir.display());
    stderr
}

fn refused(dir: &Path, args: &[&str], needles: &[&str]) -> String {
    refused_at(dir, MEMORY_CAP_KIB, args, needles)
}

/// A glTF whose root node has `instances` children drawing one mesh of `triangles` triangles.
fn instanced(dir: &Path, name: &str, triangles: usize, instances: usize) -> String {
    let positions: Vec<[f32; 3]> =
        (0..triangles).flat_map(|t| [[t as f32, 0.0, 0.0], [t as f32 + 1.0, 0.0, 0.0], [t as f32, 1.0, 0.0]]).collect();
    let children: Vec<String> = (1..=instances).map(|i| i.to_string()).collect();
    let nodes = format!(r#"[{{"children":[{}]}}{}]"#, children.join(","), r#",{"mesh":0}"#.repeat(instances));
    write_gltf(dir, name, &positions, &nodes, "").to_str().unwrap().to_string()
}

/// A PNG of `side`x`side` pixels as far as its header says (signature, IHDR, an empty IDAT,
/// IEND): what the loader reads before deciding to decode, in a few dozen bytes.
fn png_header(side: u32) -> Vec<u8> {
    fn crc(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    let chunk = |kind: &[u8], data: &[u8]| {
        let body = [kind, data].concat();
        [&(data.len() as u32).to_be_bytes()[..], &body, &crc(&body).to_be_bytes()].concat()
    };
    let ihdr = [&side.to_be_bytes()[..], &side.to_be_bytes(), &[8, 6, 0, 0, 0]].concat();
    [&b"\x89PNG\r\n\x1a\n"[..], &chunk(b"IHDR", &ihdr), &chunk(b"IDAT", &[]), &chunk(b"IEND", &[])].concat()
}

/// Kind 2: a small file amplified by instancing or by image entries naming one large image is
/// refused from its estimate, before any BVH is built or any image decoded.
#[test]
fn amplifying_scenes_are_refused_from_their_estimates() {
    let dir = scratch("limits", "scenes");
    let trace =
        |scene: &str| ["trace", "--cpu", "--resolution", "4x4", "--scene", scene, "--out", "x.exr"].map(String::from);
    let run = |scene: &str, cap_kib: u64, needles: &[&str]| {
        let args = trace(scene);
        refused_at(&dir, cap_kib, &args.iter().map(String::as_str).collect::<Vec<_>>(), needles)
    };
    // 20,000 instances of 6,000 triangles: beyond the stated limit whatever the memory.
    let many = instanced(&dir, "many", 6000, 20_000);
    run(
        &many,
        MEMORY_CAP_KIB,
        &["many.gltf: its node tree draws 120000000 triangles after instancing, more than the 100000000 a scene may \
           have: instance its meshes fewer times or simplify them"],
    );
    // 2,000 instances: 12 million triangles, within the limit, beyond a 4 GiB address space.
    let some = instanced(&dir, "some", 6000, 2000);
    run(
        &some,
        MEMORY_CAP_KIB,
        &[
            "some.gltf: loading it needs about 7.2 GiB of host memory (12000000 triangles after instancing at 640 B \
             each; 0 image entries naming 0 distinct image(s) decode to 0.0 GiB of RGBA8 textures), more than the",
            "this process may still take (what its address-space limit leaves (RLIMIT_AS, ulimit -v)): simplify the \
             scene or downscale its images, or run with more memory",
        ],
    );
    // Eight entries naming one 16384² PNG are one texture of 1 GiB: within the texture limit,
    // beyond a 2.5 GiB address space with its decode; eight such files are beyond the limit.
    std::fs::write(dir.join("big.png"), png_header(16384)).unwrap();
    let mut images = Vec::new();
    for i in 0..8 {
        std::fs::write(dir.join(format!("big{i}.png")), png_header(16384)).unwrap();
        images.push(format!(r#"{{"uri":"big{i}.png"}}"#));
    }
    let shared = format!(r#","images":[{}]"#, [r#"{"uri":"big.png"}"#; 8].join(","));
    let shared = write_gltf(&dir, "shared", &TRIANGLE, r#"[{"mesh":0}]"#, &shared);
    run(
        shared.to_str().unwrap(),
        5 << 19,
        &[
            "shared.gltf: loading it needs about 3.0 GiB of host memory (1 triangles after instancing at 640 B each; 8 \
             image entries naming 1 distinct image(s) decode to 1.0 GiB of RGBA8 textures), more than the",
            "(what its address-space limit leaves (RLIMIT_AS, ulimit -v))",
        ],
    );
    let distinct = format!(r#","images":[{}]"#, images.join(","));
    let distinct = write_gltf(&dir, "distinct", &TRIANGLE, r#"[{"mesh":0}]"#, &distinct);
    run(
        distinct.to_str().unwrap(),
        MEMORY_CAP_KIB,
        &["distinct.gltf: 8 image entries naming 8 distinct image(s) decode to 8.0 GiB of RGBA8 textures, more than \
           the 4.0 GiB a scene's textures may have: downscale its images or use fewer"],
    );
}

/// Kind 3: explicit sources passed the old count (δ-edges only), then the compiler's N² band
/// edges took 5 GB.
#[test]
fn fine_plans_with_explicit_sources_are_refused_before_planning() {
    let dir = scratch("limits", "plan");
    refused(
        &dir,
        &["plan", "--lf", "4096x1", "--gpus", "64", "--scheme", "fine-all", "--sources", "0,99"],
        &["error: --scheme fine-all over 4096 views (--lf) and 64 devices (--gpus/--fake-devices) with 2 source(s) \
           (--sources) would be about 356466432 pass instances, dependencies and copies (at most 4000000): use fewer \
           devices, fewer views (--lf), fewer --sources, or --scheme multi-source"],
    );
}

/// Kind 4: a matrix of 10^7 cells in a few kilobytes of TOML is refused before any cell is
/// built, naming its axes.
#[test]
fn bench_matrices_beyond_ten_thousand_cells_are_refused() {
    let dir = scratch("limits", "matrix");
    let list = |n: u32| (1..=n).map(|v| v.to_string()).collect::<Vec<_>>().join(", ");
    let toml = format!(
        "[[case]]\nname = \"a\"\nargs = \"--lf 2x1\"\n[[matrix]]\npipelines = [\"path-trace\"]\nspp = [{}]\n\
         devices = [{}]\ndenoise = [\"on\", \"off\"]\n",
        list(65536),
        list(64)
    );
    std::fs::write(dir.join("m.toml"), toml).unwrap();
    refused(
        &dir,
        &["bench", "--matrix", "m.toml", "--out-dir", "out"],
        &["the matrix makes 8388608 cells, more than the 10000 a bench may run; slice 1 alone makes 8388608 (cases 1 \
           × pipelines 1 × schemes 1 × sources_per_set 1 × spp 65536 × denoise 2 × devices 64"],
    );
}

/// Kind 9: the host-memory check compares with what the process's own address-space limit
/// leaves, not with the machine's free memory; lavapipe's logical devices count.
#[test]
fn runs_are_checked_against_the_address_space_limit() {
    let dir = scratch("limits", "rlimit");
    // 1 GiB: less than any machine that runs the tests has available, so the limit that binds
    // is the process's own.
    let cap = 1 << 20;
    refused_at(
        &dir,
        cap,
        &["trace", "--cpu", "--resolution", "8192x8192", "--out", "x.exr"],
        &[
            "error: 8192x8192 (--resolution) read back at 128 B per pixel: about 8.0 GiB of host memory needed",
            "(what its address-space limit leaves (RLIMIT_AS, ulimit -v)): lower --resolution",
        ],
    );
    refused_at(
        &dir,
        cap,
        &["render", "--lf", "8x8", "--resolution", "16x16", "--fake-devices", "64", "--out-dir", "lf"],
        &[
            "64 view(s) (--lf) × 16x16 (--resolution) read back at 128 B per pixel, and 64 logical device(s) \
             (--gpus/--fake-devices) at about",
            "MiB of address space each: about",
            "of address space needed, but this process may map only",
            "(what its address-space limit leaves (RLIMIT_AS, ulimit -v)): lower --lf, --resolution or --gpus/--fake-devices",
        ],
    );
}

/// Issue 38: logical devices of one GPU that would together outgrow its device-local heap are
/// refused once the devices are known, before anything is allocated or written. lavapipe's heap
/// is the machine's memory (`MemTotal`), and under fine-all each of 8 logical devices holds every
/// view (about 400 B a pixel): views of `MemTotal` / 1024 pixels in all then need about three
/// heaps, while the host reads back an eighth of the memory.
#[test]
fn logical_devices_beyond_their_gpus_heap_are_refused_before_allocating() {
    let dir = scratch("limits", "heap");
    let side = (mem_total_bytes() / 1024 / 16).isqrt() / 16 * 16;
    let resolution = format!("{side}x{side}");
    // Room for the read-back, Vulkan and 8 devices' threads (what the host check counts), so
    // the limit that binds is the GPU heap's; a regression that allocates fails under the cap.
    let cap_kib = (mem_total_bytes() / 8 + (16 << 30)) >> 10;
    let args = ["-q", "render", "--lf", "4x4", "--resolution", &resolution, "--scheme", "fine-all"];
    let opening = format!(
        "error: --scheme fine-all over 8 logical device(s) (--fake-devices 8) with 16 view(s) (--lf) × {resolution} \
         (--resolution) does not fit in GPU memory: physical GPU "
    );
    refused_at(
        &dir,
        cap_kib,
        &args.into_iter().chain(["--fake-devices", "8", "--out-dir", "lf"]).collect::<Vec<_>>(),
        &[
            &opening,
            "for device(s) 0, 1, 2, 3, 4, 5, 6, 7 (",
            "of plan and scene, and 0.5 GiB each that the driver and allocator take unreported), but its memory heap has",
            "GiB: use fewer logical devices per GPU (--fake-devices) or --scheme multi-source, or lower --lf or --resolution",
        ],
    );
}

/// The machine's memory, from /proc/meminfo.
fn mem_total_bytes() -> u64 {
    let info = std::fs::read_to_string("/proc/meminfo").unwrap();
    let line = info.lines().find(|l| l.starts_with("MemTotal:")).unwrap();
    let kib: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kib << 10
}

/// Kind 11: saved frames are estimated against the free space of --out-dir's filesystem before
/// any work (37 TB here: more than any disk the tests run on); a refusal for too long a run
/// names --frames; a run over several limits names every one.
#[test]
fn saved_frames_beyond_the_disk_and_long_runs_name_every_flag() {
    let dir = scratch("limits", "disk");
    refused(
        &dir,
        &["-q", "render", "--lf", "16x8", "--resolution", "256x256", "--layers", "--frames", "100000"]
            .into_iter()
            .chain(["--save-every", "1", "--out-dir", "lf"])
            .collect::<Vec<_>>(),
        &[
            "error: --frames 100000 with --save-every 1 saves 99999 frame(s) of 128 view(s) (--lf) at 256x256 \
             (--resolution), 11 float channel(s) per EXR (--layers adds up to 8): about 39264.5 GiB (42159883453612 \
             bytes) with the final pictures, but the filesystem of --out-dir lf has",
            "free: raise --save-every, lower --frames, --lf or --resolution, or free space",
        ],
    );
    refused(
        &dir,
        &["render", "--lf", "64x64", "--resolution", "64x64", "--spp", "64", "--frames", "100000", "--out-dir", "lf"],
        &["error: 1.07e14 paths (4096 view(s) (--lf) × 100001 frame(s) (--frames, --warmup) × 64x64 (--resolution) × \
           64 spp (--spp)) would take 29.8 h even at 1e9 paths/s: lower --lf, --frames, --warmup, --resolution or \
           --spp (at most 1e14 paths)"],
    );
    // Too long and too large at once: both limits are named, the disk's with its bytes, so that
    // lowering --spp alone does not just lead to the next refusal.
    refused(
        &dir,
        &["-q", "render", "--lf", "32x32", "--resolution", "64x64", "--spp", "256", "--frames", "100000"]
            .into_iter()
            .chain(["--save-every", "1", "--layers", "--out-dir", "lf"])
            .collect::<Vec<_>>(),
        &[
            "error: 2 limits exceeded: (1) 1.07e14 paths (1024 view(s) (--lf) × 100001 frame(s) (--frames, --warmup) × \
             64x64 (--resolution) × 256 spp (--spp)) would take 29.8 h even at 1e9 paths/s",
            "; (2) --frames 100000 with --save-every 1 saves 99999 frame(s) of 1024 view(s) (--lf) at 64x64",
            "bytes) with the final pictures, but the filesystem of --out-dir lf has",
            "bytes) free: raise --save-every, lower --frames, --lf or --resolution, or free space",
        ],
    );
    // A plan too large to hold and a run too long: the plan's limit first, then the duration's
    // (the host memory's may follow under this test's address-space cap).
    refused(
        &dir,
        &["-q", "render", "--lf", "64x64", "--resolution", "64x64", "--fake-devices", "8", "--scheme", "fine-all"]
            .into_iter()
            .chain(["--spp", "65536", "--frames", "1000", "--out-dir", "lf"])
            .collect::<Vec<_>>(),
        &[
            "limits exceeded: (1) --scheme fine-all over 4096 views (--lf) and 8 devices (--gpus/--fake-devices) with 8 \
             source(s) would be about 12766720 pass instances",
            "; (2) 1.10e15 paths (4096 view(s) (--lf) × 1001 frame(s) (--frames, --warmup) × 64x64 (--resolution) × \
             65536 spp (--spp)) would take 13 days",
        ],
    );
}

/// The PIDs whose parent is `parent`, from /proc.
fn children_of(parent: u32) -> Vec<u32> {
    let mut children = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Some(pid) = entry.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else { continue };
        if let Some((_, ppid)) = stat(pid) {
            if ppid == parent {
                children.push(pid);
            }
        }
    }
    children
}

/// A process's state letter and parent PID, from /proc/PID/stat (None once it is gone).
fn stat(pid: u32) -> Option<(char, u32)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // "pid (comm) state ppid ...": comm may hold spaces, so split after its last ')'.
    let mut fields = text[text.rfind(')')? + 1..].split_whitespace();
    let state = fields.next()?.chars().next()?;
    Some((state, fields.next()?.parse().ok()?))
}

/// Kind 10: a bench ended by SIGTERM takes its running cell's render with it, and no cell
/// result appears afterwards.
#[cfg(target_os = "linux")]
#[test]
fn bench_children_end_with_the_bench() {
    let dir = scratch("limits", "bench-children");
    let bench = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["bench", "--common", "--lf 2x1 --resolution 8x8", "--pipelines", "path-trace", "--fake-devices", "1"])
        .args(["--frames", "100000", "--out-dir", "out"])
        .current_dir(&dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut bench = bench;
    let render = loop {
        if let Some(&pid) = children_of(bench.id()).first() {
            break pid;
        }
        if let Some(status) = bench.try_wait().unwrap() {
            let mut stderr = String::new();
            std::io::Read::read_to_string(bench.stderr.as_mut().unwrap(), &mut stderr).unwrap();
            panic!("bench ended ({status}) before its first cell: {stderr}");
        }
        assert!(start.elapsed() < HANG_GUARD, "bench started no cell within {HANG_GUARD:?}");
        std::thread::sleep(Duration::from_millis(20));
    };
    // Let the cell get into its frames, then end bench as a job control or a batch system would.
    std::thread::sleep(Duration::from_secs(2));
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(bench.id() as i32), nix::sys::signal::Signal::SIGTERM).unwrap();
    let out = wait_or_kill(bench, "bench");
    assert_eq!(out.status.code(), Some(130), "{}", String::from_utf8_lossy(&out.stderr));
    // Gone, or a zombie that no longer runs (whoever adopted it may not have reaped it yet).
    let start = Instant::now();
    while stat(render).is_some_and(|(state, _)| state != 'Z') {
        if start.elapsed() > HANG_GUARD {
            let _ =
                nix::sys::signal::kill(nix::unistd::Pid::from_raw(render as i32), nix::sys::signal::Signal::SIGKILL);
            panic!("the cell's render (pid {render}) outlived bench by {HANG_GUARD:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let results: Vec<_> =
        snapshot(&dir).into_keys().filter(|p| p.file_name().is_some_and(|n| n == "render.json")).collect();
    assert!(results.is_empty(), "a cell result appeared after bench ended: {results:?}");
}
