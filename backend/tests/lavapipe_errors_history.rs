//! Exact error variants of the backend, the validation messenger, and history resources that
//! survive from frame to frame (lavapipe or any Vulkan device).

use parallax_backend::kernels::builtin_kernels;
use parallax_backend::{
    BackendError, Context, ContextDesc, DeviceSelection, ExecOptions, Executor, KernelRegistry, Plan, PlanAccess,
    PlanCopy, PlanError, PlanOp, PlanPass, PlanResource, ResourceKind, Rows, TexelFormat, Validation,
};

fn context(selection: DeviceSelection) -> Result<Context, BackendError> {
    Context::new(&ContextDesc { selection, validation: Validation::Core })
}

#[test]
fn asking_for_more_gpus_than_exist_names_both_counts() {
    let err = context(DeviceSelection::Gpus(64)).err().unwrap();
    match err {
        BackendError::NotEnoughGpus { requested, available } => {
            assert_eq!(requested, 64);
            assert!((1..64).contains(&available));
        }
        other => panic!("unexpected {other}"),
    }
}

#[test]
fn zero_devices_is_refused() {
    assert!(matches!(context(DeviceSelection::FakeDevices(0)).err().unwrap(), BackendError::ZeroDevices));
}

#[test]
fn validation_messages_fail_the_check() {
    use ash::vk;
    let ctx = context(DeviceSelection::FakeDevices(1)).unwrap();
    ctx.check_validation().unwrap();
    let device = ctx.devices()[0].raw();
    // size 0 violates VUID-VkBufferCreateInfo-size-00912.
    let info = vk::BufferCreateInfo::default().size(0).usage(vk::BufferUsageFlags::TRANSFER_DST);
    if let Ok(buffer) = unsafe { device.create_buffer(&info, None) } {
        unsafe { device.destroy_buffer(buffer, None) };
    }
    match ctx.check_validation() {
        Err(BackendError::Validation { messages }) => {
            assert!(messages.iter().any(|m| m.contains("VUID-VkBufferCreateInfo-size")), "{messages:?}");
        }
        other => panic!("expected a validation failure, got {other:?}"),
    }
    ctx.check_validation().unwrap();
}

/// Device 1 accumulates into `acc` every frame; device 0 receives a copy each frame.
fn history_plan(size: u32) -> Plan {
    let all = Rows::new(0, size);
    Plan {
        resources: vec![PlanResource {
            name: "acc".into(),
            view: 0,
            width: size,
            height: size,
            format: TexelFormat::Rgba32Float,
            kind: ResourceKind::Image,
            exported: false,
            reset: None,
        }],
        passes: vec![PlanPass {
            name: "accumulate".into(),
            view: 0,
            rows: all,
            device: 1,
            reads: vec![PlanAccess { resource: 0, version: 0, rows: all }],
            history_reads: vec![],
            writes: vec![PlanAccess { resource: 0, version: 1, rows: all }],
        }],
        copies: vec![PlanCopy { resource: 0, version: 1, rows: all, from: 1, to: 0 }],
        devices: vec![
            vec![PlanOp::Wait(0), PlanOp::CopyIn(0)],
            vec![PlanOp::Pass(0), PlanOp::CopyOut(0), PlanOp::Signal(0)],
        ],
    }
}

#[test]
fn history_survives_frames_in_flight_without_re_recording() {
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let options = ExecOptions { frames_in_flight: 3, ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, history_plan(16), builtin_kernels(), options).unwrap();
    let frames = 7u32;
    for _ in 0..frames {
        exec.run_frame().unwrap();
    }
    let bytes = exec.read_image(0, 0).unwrap();
    let expected = (frames * (frames + 1) / 2) as f32;
    let values: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    assert!(values.iter().all(|&v| v == expected), "expected {expected}, got {:?}", &values[..4]);
    assert_eq!(exec.recordings(), 1);
    drop(exec);
    ctx.check_validation().unwrap();
}

#[test]
fn plan_errors_are_reported_before_any_gpu_work() {
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let mut plan = history_plan(8);
    plan.devices[0].clear();
    let err = Executor::new(&ctx, plan, builtin_kernels(), ExecOptions::default()).err().unwrap();
    assert!(matches!(err, BackendError::Plan(PlanError::CopyOpMisplaced { copy: 0, op: "Wait" })), "{err}");
    let err = Executor::new(&ctx, history_plan(8), KernelRegistry::new(), ExecOptions::default()).err().unwrap();
    match err {
        BackendError::UnknownPass { pass, registered } => {
            assert_eq!(pass, "accumulate");
            assert!(registered.is_empty());
        }
        other => panic!("unexpected {other}"),
    }
    let one = context(DeviceSelection::FakeDevices(1)).unwrap();
    let err = Executor::new(&one, history_plan(8), builtin_kernels(), ExecOptions::default()).err().unwrap();
    assert!(matches!(err, BackendError::Plan(PlanError::DeviceCount { plan: 2, context: 1 })), "{err}");
}

#[test]
fn integer_images_go_through_the_uint_binding_and_across_devices() {
    use parallax_backend::kernels::{reference_fill, reference_mask};
    let size = 16;
    let all = Rows::new(0, size);
    let image = |name: &str, format| PlanResource {
        name: name.into(),
        view: 0,
        width: size,
        height: size,
        format,
        kind: ResourceKind::Image,
        exported: false,
        reset: None,
    };
    let write = |resource| PlanAccess { resource, version: 1, rows: all };
    // Device 1 writes a uint mask and a float image side by side (indices interleave the two
    // bindings); both travel to device 0.
    let plan = Plan {
        resources: vec![image("mask", TexelFormat::R32Uint), image("radiance", TexelFormat::Rgba32Float)],
        passes: vec![
            PlanPass {
                name: "fill_mask".into(),
                view: 0,
                rows: all,
                device: 1,
                reads: vec![],
                history_reads: vec![],
                writes: vec![write(0)],
            },
            PlanPass {
                name: "fill".into(),
                view: 0,
                rows: all,
                device: 1,
                reads: vec![],
                history_reads: vec![],
                writes: vec![write(1)],
            },
        ],
        copies: vec![
            PlanCopy { resource: 0, version: 1, rows: all, from: 1, to: 0 },
            PlanCopy { resource: 1, version: 1, rows: all, from: 1, to: 0 },
        ],
        devices: vec![
            vec![PlanOp::Wait(0), PlanOp::CopyIn(0), PlanOp::Wait(1), PlanOp::CopyIn(1)],
            vec![
                PlanOp::Pass(0),
                PlanOp::Pass(1),
                PlanOp::CopyOut(0),
                PlanOp::Signal(0),
                PlanOp::CopyOut(1),
                PlanOp::Signal(1),
            ],
        ],
    };
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let mut exec = Executor::new(&ctx, plan, builtin_kernels(), ExecOptions::default()).unwrap();
    exec.run_frame().unwrap();
    let mask = exec.read_image(0, 0).unwrap();
    let radiance = exec.read_image(0, 1).unwrap();
    let words = |b: &[u8]| b.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect::<Vec<_>>();
    let mask: Vec<u32> = words(&mask).into_iter().map(u32::from_le_bytes).collect();
    let radiance: Vec<f32> = words(&radiance).into_iter().map(f32::from_le_bytes).collect();
    let expected_mask: Vec<u32> = (0..size).flat_map(|y| (0..size).map(move |x| reference_mask(x, y, 0))).collect();
    let expected_radiance: Vec<f32> =
        (0..size).flat_map(|y| (0..size).flat_map(move |x| reference_fill(x, y, 0))).collect();
    assert_eq!(mask, expected_mask);
    assert_eq!(radiance, expected_radiance);
    drop(exec);
    ctx.check_validation().unwrap();
}

/// One raster pass instance per device, each over a row band of the same image; bands gathered
/// on device 0.
fn raster_plan(devices: usize, size: u32) -> Plan {
    let bands: Vec<Rows> =
        (0..devices as u32).map(|d| Rows::new(size * d / devices as u32, size * (d + 1) / devices as u32)).collect();
    let mut plan = Plan {
        resources: vec![PlanResource {
            name: "gbuffer".into(),
            view: 5,
            width: size,
            height: size,
            format: TexelFormat::Rgba32Float,
            kind: ResourceKind::Image,
            exported: false,
            reset: None,
        }],
        devices: vec![Vec::new(); devices],
        ..Plan::default()
    };
    for (d, &rows) in bands.iter().enumerate() {
        plan.passes.push(PlanPass {
            name: "raster_demo".into(),
            view: 5,
            rows,
            device: d,
            reads: vec![],
            history_reads: vec![],
            writes: vec![PlanAccess { resource: 0, version: 1, rows }],
        });
        plan.devices[d].push(PlanOp::Pass(d));
        if d != 0 {
            let c = plan.copies.len();
            plan.copies.push(PlanCopy { resource: 0, version: 1, rows, from: d, to: 0 });
            plan.devices[d].extend([PlanOp::CopyOut(c), PlanOp::Signal(c)]);
            plan.devices[0].extend([PlanOp::Wait(c), PlanOp::CopyIn(c)]);
        }
    }
    plan
}

#[test]
fn raster_passes_render_row_bands_with_depth_test_on_any_device_count() {
    use parallax_backend::kernels::reference_raster;
    let size = 32;
    let expected: Vec<f32> =
        (0..size).flat_map(|y| (0..size).flat_map(move |x| reference_raster(x, y, 5, size))).collect();
    for devices in [1, 2, 3] {
        let ctx = context(DeviceSelection::FakeDevices(devices)).unwrap();
        let mut exec =
            Executor::new(&ctx, raster_plan(devices, size), builtin_kernels(), ExecOptions::default()).unwrap();
        exec.run_frame().unwrap();
        exec.run_frame().unwrap();
        let values: Vec<f32> = exec
            .read_image(0, 0)
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(values, expected, "{devices} device(s)");
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

fn weighted_plan(size: u32) -> Plan {
    let all = Rows::new(0, size);
    Plan {
        resources: (0..2)
            .map(|v| PlanResource {
                name: "w".into(),
                view: v,
                width: size,
                height: size,
                format: TexelFormat::Rgba32Float,
                kind: ResourceKind::Image,
                exported: false,
                reset: None,
            })
            .collect(),
        passes: (0..2)
            .map(|v| PlanPass {
                name: "weighted_fill".into(),
                view: v,
                rows: all,
                device: v as usize,
                reads: vec![],
                history_reads: vec![],
                writes: vec![PlanAccess { resource: v as usize, version: 1, rows: all }],
            })
            .collect(),
        copies: vec![PlanCopy { resource: 1, version: 1, rows: all, from: 1, to: 0 }],
        devices: vec![
            vec![PlanOp::Pass(0), PlanOp::Wait(0), PlanOp::CopyIn(0)],
            vec![PlanOp::Pass(1), PlanOp::CopyOut(0), PlanOp::Signal(0)],
        ],
    }
}

#[test]
fn global_buffers_and_frame_data_reach_kernels_by_address() {
    use parallax_backend::kernels::reference_fill;
    let size = 16;
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let mut exec = Executor::new(&ctx, weighted_plan(size), builtin_kernels(), ExecOptions::default()).unwrap();
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let check = |exec: &mut Executor, weights: [f32; 2], offset: f32| {
        for view in 0..2u32 {
            let bytes = exec.read_image(0, view as usize).unwrap();
            let got: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            let expected: Vec<f32> = (0..size)
                .flat_map(|y| (0..size).flat_map(move |x| reference_fill(x, y, view)))
                .map(|p| p * weights[view as usize] + offset)
                .collect();
            assert_eq!(got, expected, "view {view}, weights {weights:?}, offset {offset}");
        }
    };

    // Running before the kernel's buffer exists is an error naming it.
    match exec.run_frame() {
        Err(BackendError::UnknownBuffer { name, device: 0 }) => assert_eq!(name, "weights"),
        other => panic!("expected UnknownBuffer, got {other:?}"),
    }
    exec.upload_buffer("weights", &floats(&[0.5, 2.0])).unwrap();
    exec.set_frame_data(&floats(&[0.25])).unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [0.5, 2.0], 0.25);
    let recorded = exec.recordings();

    // Same size: contents change in place, nothing is re-recorded; frame data changes per frame.
    exec.upload_buffer("weights", &floats(&[1.0, 4.0])).unwrap();
    exec.set_frame_data(&floats(&[0.5])).unwrap();
    exec.run_frame().unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [1.0, 4.0], 0.5);
    assert_eq!(exec.recordings(), recorded);

    // Another size moves the buffer: recorded again before the next frame.
    exec.upload_buffer("weights", &floats(&[0.25, 0.125, 9.0])).unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [0.25, 0.125], 0.5);
    assert_eq!(exec.recordings(), recorded + 1);

    let too_big = vec![0u8; (ExecOptions::default().frame_data_bytes + 4) as usize];
    assert!(matches!(exec.set_frame_data(&too_big), Err(BackendError::FrameDataTooLarge { .. })));
    drop(exec);
    ctx.check_validation().unwrap();
}
