//! Kernels from outside `shaders/`: GLSL in this test's folder (`tests/user_kernels/`),
//! compiled at run time with parallax-glsl, handed to the executor as a `ShaderLibrary` beside
//! the testkit's (compiled by its build.rs) and run on two logical devices after the testkit's
//! fill, against a CPU reference (validation on);
//! bytes that are not SPIR-V are refused with the exact error, and so is a kernel whose
//! push-constant struct does not match its shader's block.

use std::path::Path;
use std::sync::Arc;

use parallax_backend::{
    BACKEND_SHADERS, BackendError, Context, ContextDesc, DeviceSelection, ExecOptions, Executor, InstanceId,
    KernelGraph, KernelPlan, PassInstance, PassKernel, PassParams, Recorder, SearchedShaders, ShaderLibrary,
    SpirvDefect, Validation, shader_names,
};
use parallax_glsl::{CompiledShader, Compiler};
use parallax_graph::{
    AllocId, AssignStrategy, DeviceId, Format, LightField, PartitionConfig, ReadSlot, Rig, Role, Scheme, WriteSlot,
    compile,
};
use parallax_testkit::kernels::{FillKernel, declare_writer, reference_fill};

const SIZE: u32 = 16;
const DEVICES: u32 = 2;

/// The shaders of `tests/user_kernels/`, compiled into a folder of cargo's temporary folder of
/// `test`'s own (tests run in parallel).
fn compile_user_shaders(test: &str) -> Vec<CompiledShader> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("user_kernels");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("user_kernels").join(test);
    std::fs::create_dir_all(&out).unwrap();
    let includes = [src.join("include"), parallax_glsl::parallax_include_dir().to_path_buf()];
    Compiler::new().compile_dir(&src, &[&includes[0], &includes[1]], &out).unwrap()
}

/// The testkit's shaders and `shaders`.
fn user_library(shaders: &[CompiledShader]) -> ShaderLibrary {
    shaders.iter().fold(parallax_testkit::shaders(), |library, shader| {
        library.with_spirv_bytes(&shader.name, &std::fs::read(&shader.spirv).unwrap()).unwrap()
    })
}

/// Dispatches the user shader `shader` with its read as `src0` and its write as `dst`.
struct ReadWriteKernel {
    shader: &'static str,
    src: ReadSlot,
    dst: WriteSlot,
}

impl PassKernel for ReadWriteKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let (src, dst) = (pass.read(self.src)?.alloc, pass.write(self.dst)?.alloc);
        let params = PassParams { src0: rec.image(src)?, ..rec.row_params(pass, dst)? };
        rec.dispatch_rows(self.shader, params)
    }
}

/// `scale_swap.glsl` on the CPU, applied to the testkit's fill pattern.
fn reference_scale_swap(x: u32, y: u32, view: u32) -> [f32; 4] {
    let v = reference_fill(x, y, view);
    let offset = view as f32 * 0.25;
    [v[1] * 0.5 + offset, v[0] * 0.5 + offset, v[3] * 0.5 + offset, v[2] * 0.5 + offset]
}

/// testkit `fill` → user pass `user` (kernel dispatching `shader`) on every view of a 2×1 light
/// field over two devices, the result gathered on device 0. Returns the plan and, per view,
/// the resource of the result.
fn fill_then_user_pass(shader: &'static str) -> (KernelPlan, Vec<AllocId>) {
    let lf = LightField::new("2x1".parse().unwrap(), None, Some((SIZE, SIZE)), Rig::default()).unwrap();
    let config = PartitionConfig {
        devices: DEVICES,
        scheme: Scheme::MultiSource,
        assign: AssignStrategy::Compact,
        sources: None,
    };
    let plan = parallax_graph::Partition::new(&lf, &config).unwrap();
    let mut g = KernelGraph::with_payload(plan.topology.clone());
    let mut pattern = g.image("pattern", Format::Rgba32f);
    let mut output = g.image("output", Format::Rgba32f);
    declare_writer(&mut g, "fill", Role::All, &mut pattern, |out| FillKernel { out }).add();
    let mut pass = g.pass("user", Role::All);
    let (src, dst) = (pass.read_slot(&pattern), pass.write_slot(&mut output));
    pass.kernel(Arc::new(ReadWriteKernel { shader, src, dst })).add();
    g.export(&output);
    let schedule = compile(&g, &plan).unwrap();
    let plan = KernelPlan::from_schedule(&g, &schedule).unwrap();
    let outputs = (0..2).map(|v| plan.final_output(output.family(), v).unwrap().1).collect();
    (plan, outputs)
}

fn context() -> Context {
    Context::new(&ContextDesc {
        selection: DeviceSelection::FakeDevices(DEVICES as usize),
        validation: Validation::Core,
    })
    .expect("a Vulkan device (apt-get install mesa-vulkan-drivers) and validation layers")
}

#[test]
fn a_kernel_compiled_outside_shaders_runs_on_every_device_like_the_cpu() {
    let shaders = compile_user_shaders("runs");
    let names: Vec<&str> = shaders.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["scale_swap"]);
    // Its own include and the backend's, so a build script reruns when either changes.
    let deps: Vec<_> = shaders[0].dependencies.iter().filter_map(|d| d.file_name()).collect();
    assert_eq!(deps, ["scale_swap.comp", "scale_swap.glsl", "bindless.glsl"]);

    let ctx = context();
    let (plan, outputs) = fill_then_user_pass("scale_swap");
    assert!(!plan.copies.is_empty(), "the second view is gathered from device 1");
    let options = ExecOptions { shaders: user_library(&shaders), ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    for _ in 0..2 {
        exec.run_frame().unwrap();
    }
    exec.finish().unwrap();
    for (view, &resource) in outputs.iter().enumerate() {
        let bytes = exec.read_resource(DeviceId(0), resource).unwrap();
        let values: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let view = view as u32;
        let expected: Vec<f32> =
            (0..SIZE).flat_map(|y| (0..SIZE).flat_map(move |x| reference_scale_swap(x, y, view))).collect();
        assert_eq!(values, expected, "view {view}");
    }
    drop(exec);
    ctx.check_validation().unwrap();
}

#[test]
fn a_kernel_naming_no_known_shader_lists_where_it_looked() {
    let ctx = context();
    let (plan, _) = fill_then_user_pass("no_such_shader");
    let options = ExecOptions { shaders: user_library(&compile_user_shaders("unknown")), ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    match exec.run_frame() {
        Err(BackendError::UnknownShader { name, searched }) => {
            assert_eq!(name, "no_such_shader");
            let mut expected: Vec<String> = parallax_testkit::shaders().names().map(str::to_string).collect();
            expected.push("scale_swap".into());
            expected.sort();
            // The user's library (the testkit's, with scale_swap added), then the backend's own.
            let builtin =
                SearchedShaders { origin: BACKEND_SHADERS.into(), names: shader_names().map(str::to_string).collect() };
            let user = SearchedShaders { origin: "the shaders of parallax-testkit".into(), names: expected };
            assert_eq!(searched, [user, builtin]);
        }
        other => panic!("expected BackendError::UnknownShader, got {other:?}"),
    }
    drop(exec);
    ctx.check_validation().unwrap();
}

/// `PassParams` with `y0` and `y1` swapped: the mistake a hand-packed struct makes.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct SwappedRows {
    dst: u32,
    src0: u32,
    src1: u32,
    view: u32,
    y1: u32,
    y0: u32,
    width: u32,
    param: u32,
}

parallax_backend::push_constants!(SwappedRows { dst, src0, src1, view, y1, y0, width, param });

/// Dispatches the testkit's `fill` with [`SwappedRows`] into its write.
struct SwappedRowsKernel {
    dst: WriteSlot,
}

impl PassKernel for SwappedRowsKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let p = rec.row_params(pass, pass.write(self.dst)?.alloc)?;
        let push =
            SwappedRows { dst: p.dst, src0: 0, src1: 0, view: p.view, y1: p.y1, y0: p.y0, width: p.width, param: 0 };
        rec.dispatch("fill", &push, [p.width.div_ceil(8), pass.region.len().div_ceil(8), 1])
    }
}

#[test]
fn a_push_constant_struct_unlike_the_shaders_block_is_refused_naming_the_pass_and_field() {
    let ctx = context();
    let topology = parallax_graph::ViewTopology::all_sources(1, SIZE, SIZE);
    let mut g = KernelGraph::with_payload(topology);
    let mut out = g.image("out", Format::Rgba32f);
    let mut pass = g.pass("swapped", Role::All);
    let kernel = SwappedRowsKernel { dst: pass.write_slot(&mut out) };
    pass.kernel(Arc::new(kernel)).add();
    g.export(&out);
    let placement = parallax_graph::BandedPlacement { devices: DEVICES, bands: 1 };
    let plan = KernelPlan::from_schedule(&g, &compile(&g, &placement).unwrap()).unwrap();
    let options = ExecOptions { shaders: parallax_testkit::shaders(), ..ExecOptions::default() };
    let result = Executor::new(&ctx, plan, options).and_then(|mut exec| exec.run_frame());
    match result {
        Err(BackendError::PushConstantLayout { pass, shader, rust_type, field, .. }) => {
            assert_eq!((pass.as_str(), shader.as_str(), field.as_str()), ("swapped", "fill", "y0"));
            assert!(rust_type.ends_with("SwappedRows"), "{rust_type}");
        }
        other => panic!("expected BackendError::PushConstantLayout, got {other:?}"),
    }
    ctx.check_validation().unwrap();
}

#[test]
fn bytes_that_are_not_spirv_are_refused_naming_the_shader() {
    let spirv = std::fs::read(&compile_user_shaders("refused")[0].spirv).unwrap();
    let source =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/user_kernels/scale_swap.comp")).unwrap();
    let cases = [
        (&spirv[..spirv.len() - 1], SpirvDefect::Unaligned { bytes: spirv.len() - 1 }),
        (&spirv[..8], SpirvDefect::TooShort { words: 2 }),
        // GLSL handed over where SPIR-V belongs.
        (&source[..20], SpirvDefect::BadMagic { found: u32::from_le_bytes(*b"#ver") }),
    ];
    for (bytes, expected) in cases {
        match ShaderLibrary::new().with_spirv_bytes("scale_swap", bytes) {
            Err(BackendError::InvalidSpirv { shader, defect }) => {
                assert_eq!((shader.as_str(), &defect), ("scale_swap", &expected));
            }
            other => panic!("expected BackendError::InvalidSpirv, got {other:?}"),
        }
    }
    let err = ShaderLibrary::new().with_spirv("empty", Vec::new()).unwrap_err();
    assert!(err.to_string().starts_with("shader `empty` is not SPIR-V"), "{err}");
}

#[test]
fn include_shaders_reads_the_table_parallax_glsl_wrote() {
    // The backend's own build.rs wrote this crate's table through parallax-glsl, as a user
    // crate's build.rs would.
    let library = parallax_backend::include_shaders!().unwrap();
    assert_eq!(library.names().collect::<Vec<_>>(), shader_names().collect::<Vec<_>>());
    assert_eq!(library.spirv("bench_fill").unwrap(), parallax_backend::spirv("bench_fill").unwrap());
}
