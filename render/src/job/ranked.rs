//! `render` under `mpirun -n R` (`--features mpi`): every rank plans the same schedule for the
//! devices of all ranks together and runs the part on its own devices. Under multi-source
//! (whole sets) ranks other than 0 send their finished views to rank 0 after the last frame;
//! under a fine scheme the bands that devices of different ranks exchange, the gathers of
//! finished bands to device 0 among them, travel every frame through the executor's `remote`
//! links ([`LinkTransport`]), so rank 0 holds every view. Rank 0 writes every output as one
//! process would. A rank that fails ends the run with one message from rank 0 naming it, its
//! host and the cause; rank 0 polls against `--rank-timeout` and never waits without end; and
//! since rank 0 stages every output until all views are in, a failed run leaves nothing.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use glam::{Vec2, Vec3};
use parallax_backend::KernelPlan;
use parallax_passes::pipeline::PipelineBuilder;
use parallax_scene::Camera;

use super::faults::{RankFault, rank_fault_from_env};
use super::frames::render_frames;
use super::prepare::RenderJob;
use super::report::{RankViews, Rendered, write_outputs};
use super::view_files::output_families;
use crate::error::UsageError;
use crate::ranks::mpi::{Cluster, Collector, FrameStat, LinkTransport, Reported};
use crate::ranks::{RankLayout, RankPart, linked, views_of};
use crate::report::stages::timings;
use crate::settings::{RenderExtension, RenderSettings};

/// Runs this rank's part of the render.
pub(super) fn run(settings: &RenderSettings, extension: &mut RenderExtension, cluster: &Cluster) -> Result<()> {
    // A collective before anything can fail on one rank alone.
    let layout = cluster.layout(settings.devices.count() as u32);
    let fault = rank_fault_from_env()?;
    if cluster.rank == 0 {
        refuse(settings)?;
        lead(settings, extension, cluster, &layout, fault)
    } else {
        follow(settings, extension, cluster, &layout, fault)
    }
}

/// What only runs in one process today.
fn refuse(settings: &RenderSettings) -> Result<()> {
    if settings.save_every.is_some() {
        return Err(UsageError(
            "--save-every writes intermediate frames, which ranks do not send to rank 0 yet: drop --save-every under \
             mpirun"
                .into(),
        )
        .into());
    }
    Ok(())
}

fn extend_of(extension: &RenderExtension) -> impl Fn(PipelineBuilder) -> PipelineBuilder + '_ {
    move |builder| match &extension.stages {
        Some(stages) => stages(builder),
        None => builder,
    }
}

/// The run's settings that every rank must share (its devices are its own).
fn shared_settings(settings: &RenderSettings) -> serde_json::Value {
    let mut settings = settings.run.clone();
    if let Some(map) = settings.as_object_mut() {
        map.remove("gpus");
        map.remove("fake_devices");
    }
    settings
}

/// Rank 0: plans, sends every rank the frames, renders its own sets while listening, gathers
/// the others' views and writes the outputs.
fn lead(
    settings: &RenderSettings,
    extension: &mut RenderExtension,
    cluster: &Cluster,
    layout: &RankLayout,
    fault: Option<RankFault>,
) -> Result<()> {
    let mut job = RenderJob::prepare(settings, &extend_of(extension), layout.total(), true)?;
    job.rank = Some(rank_part(settings, &job, cluster, layout)?);
    let cameras: Vec<[u32; 12]> = (0..job.total_frames).map(|f| camera_bits(&job.camera_at(settings, f))).collect();
    cluster.send_frames(&serde_json::json!({ "settings": shared_settings(settings), "cameras": cameras }));
    let mut collector = Collector::new(cluster.size(), settings.rank_timeout);
    let mut listen = |frame: u32, _wall: Duration| {
        inject(fault, 0, frame)?;
        collector.poll(cluster)
    };
    let rendered = render_frames(settings, &mut job, extension, Some(&mut listen));
    // A link that waited in vain for a rank that failed: its own message says why.
    let mut rendered = rendered.or_else(|e| collector.poll(cluster).and(Err(e)))?;
    let finished = collector.wait_all(cluster)?;
    let global = Arc::clone(&job.compiled.exec);
    rendered.ranks = Some(gathered(settings, &mut rendered, &collector, finished, global, cluster, layout)?);
    write_outputs(settings, &job, rendered)
}

/// Ranks other than 0: render the own sets, report each frame, send the views; a failure goes
/// to rank 0, which says it.
fn follow(
    settings: &RenderSettings,
    extension: &mut RenderExtension,
    cluster: &Cluster,
    layout: &RankLayout,
    fault: Option<RankFault>,
) -> Result<()> {
    let frames = cluster.receive_frames()?;
    let rank = cluster.rank;
    let outcome = (|| -> Result<(serde_json::Value, Vec<Vec<u8>>)> {
        if frames["settings"] != shared_settings(settings) {
            bail!("its flags differ from rank 0's: give every rank the same flags (but --gpus/--fake-devices)");
        }
        let cameras: Vec<[u32; 12]> = serde_json::from_value(frames["cameras"].clone())?;
        let mut job = RenderJob::prepare(settings, &extend_of(extension), layout.total(), false)?;
        job.cameras = Some(cameras.iter().map(camera_of_bits).collect());
        job.rank = Some(rank_part(settings, &job, cluster, layout)?);
        let mut report = |frame: u32, wall: Duration| {
            inject(fault, rank, frame)?;
            cluster.send_frame_done(&FrameStat { frame, wall_ms: wall.as_secs_f64() * 1e3 });
            Ok(())
        };
        let rendered = render_frames(settings, &mut job, extension, Some(&mut report))?;
        views_to_send(settings, &job, rendered)
    })();
    match outcome {
        Ok((header, blobs)) => {
            cluster.send_done(&header, &blobs);
            Ok(())
        }
        Err(e) => {
            cluster.send_failed(&format!("{e:#}"));
            Err(Reported.into())
        }
    }
}

/// The injected fault of `rank` at `frame`, if any (`PARALLAX_FAULT`).
fn inject(fault: Option<RankFault>, rank: usize, frame: u32) -> Result<()> {
    match fault {
        Some(RankFault::Fails { rank: r, frame: f }) if (r, f) == (rank, frame) => {
            bail!("injected fault at frame {frame} (PARALLAX_FAULT=rank-fails:{rank}:{frame})")
        }
        Some(RankFault::Stalls { rank: r, frame: f }) if (r, f) == (rank, frame) => loop {
            std::thread::sleep(Duration::from_secs(3600));
        },
        _ => Ok(()),
    }
}

/// This rank's part of the run: its devices, and where its devices exchange bands with other
/// ranks' (a fine scheme), the transport of those links.
fn rank_part(settings: &RenderSettings, job: &RenderJob, cluster: &Cluster, layout: &RankLayout) -> Result<RankPart> {
    let transport: Option<std::sync::Arc<dyn parallax_backend::RemoteTransport>> =
        match linked(&job.compiled.exec, layout) {
            true => Some(LinkTransport::start(cluster, layout, settings.rank_timeout)?),
            false => None,
        };
    Ok(RankPart { layout: layout.clone(), rank: cluster.rank, transport })
}

/// A rank's finished views (the resources rank 0 writes the outputs from) and its statistics.
/// Under a fine scheme rank 0 holds the gathered layers already (the links brought their
/// bands); the rank sends only the bands of the other layers that its devices hold
/// ([`own_bands`]).
fn views_to_send(
    settings: &RenderSettings,
    job: &RenderJob,
    rendered: Rendered,
) -> Result<(serde_json::Value, Vec<Vec<u8>>)> {
    let Rendered { context, mut renderer, wall, layers, .. } = rendered;
    let views = views_of(renderer.plan());
    let part = job.rank.as_ref().context("a rank runs a part")?;
    let linked = part.transport.is_some();
    let mut listed = Vec::new();
    let mut blobs = Vec::new();
    let families = output_families(settings, job, layers);
    let (bands, band_blobs) = match linked {
        true => own_bands(&mut renderer, &families, &views, part.layout.first(part.rank))?,
        false => (Vec::new(), Vec::new()),
    };
    for family in families {
        for &view in views.iter().filter(|_| !linked) {
            match renderer.read(family, view) {
                Ok(bytes) => {
                    listed.push([family.0, view]);
                    blobs.push(bytes);
                }
                // Sources have no hole mask.
                Err(parallax_passes::PassError::MissingOutput { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }
    // Stats borrow the renderer mutably (they fold the retired frames first).
    let stats = renderer.stats().clone();
    let timing = timings(&stats, renderer.prepare_ms(), renderer.plan());
    drop(renderer);
    context.check_validation()?;
    let header = serde_json::json!({
        "devices": context.device_infos().iter().map(|d| d.name.clone()).collect::<Vec<_>>(),
        "views": views,
        "resources": listed,
        "bands": bands,
        "wall_ms_per_frame": wall.as_secs_f64() * 1e3 / f64::from(settings.frames),
        "frame_gpu_ms": timing.frame_gpu.mean_ms,
    });
    blobs.extend(band_blobs);
    Ok((header, blobs))
}

/// Bands a rank sends rank 0: `[family, view, global device]`, and one image each.
type OwnBands = (Vec<[u32; 3]>, Vec<Vec<u8>>);

/// Under a fine scheme, the row bands of `families` of `views` that were left on this rank's
/// devices (layers not gathered to device 0), as `[family, view, global device]` and one
/// whole-view image per device whose other rows are zero: rank 0 stitches them into the views.
fn own_bands(
    renderer: &mut parallax_passes::LightFieldRenderer,
    families: &[parallax_graph::FamilyId],
    views: &BTreeSet<u32>,
    first: u32,
) -> Result<OwnBands> {
    let plan = renderer.shared_plan();
    let here = plan.devices.len();
    let (mut listed, mut blobs) = (Vec::new(), Vec::new());
    for &family in families {
        for &view in views {
            let Some(bands) = plan.final_bands(family, view) else { continue };
            for device in (0..here).map(|d| parallax_graph::DeviceId(d as u32)) {
                let mine: Vec<_> = bands.iter().filter(|b| b.0 == device).collect();
                let Some(&&(_, resource, _)) = mine.first() else { continue };
                let desc = plan.resource(resource);
                let row_bytes = desc.row_bytes() as usize;
                let mut image = vec![0u8; row_bytes * desc.height as usize];
                for &&(_, resource, rows) in &mine {
                    let rows = rows.y0 as usize * row_bytes..rows.y1 as usize * row_bytes;
                    let source = renderer.executor().read_resource(device, resource)?;
                    image[rows.clone()].copy_from_slice(&source[rows]);
                }
                listed.push([family.0, view, first + device.0]);
                blobs.push(image);
            }
        }
    }
    Ok((listed, blobs))
}

/// Rank 0's gathered views and render.json's `ranks`.
fn gathered(
    settings: &RenderSettings,
    rendered: &mut Rendered,
    collector: &Collector,
    finished: Vec<crate::ranks::mpi::Finished>,
    plan: Arc<KernelPlan>,
    cluster: &Cluster,
    layout: &RankLayout,
) -> Result<RankViews> {
    let own_views = views_of(rendered.renderer.plan());
    let own_wall = rendered.wall.as_secs_f64() * 1e3 / f64::from(settings.frames);
    // Stats borrow the renderer mutably (they fold the retired frames first).
    let stats = rendered.renderer.stats().clone();
    let own_timing = timings(&stats, rendered.renderer.prepare_ms(), rendered.renderer.plan());
    let mut device_names: Vec<String> = rendered.context.device_infos().iter().map(|d| d.name.clone()).collect();
    let mut remote = HashMap::new();
    let mut bands = HashMap::new();
    let mut remote_views = BTreeSet::new();
    let mut wall_ms = own_wall;
    let mut ranks = vec![serde_json::json!({
        "rank": 0, "host": cluster.hosts[0], "devices": (0..layout.devices[0]).collect::<Vec<_>>(),
        "views": own_views, "wall_ms_per_frame": own_wall, "frame_gpu_ms": own_timing.frame_gpu.mean_ms,
        "bytes_sent": 0,
    })];
    for (i, f) in finished.into_iter().enumerate() {
        let rank = i + 1;
        let header = &f.header;
        let resources: Vec<[u32; 2]> =
            serde_json::from_value(header["resources"].clone()).context("a rank's view list")?;
        // The views whose resources it sent (none under a fine scheme: rank 0 holds them).
        remote_views.extend(resources.iter().map(|&[_, view]| view));
        let mut blobs = f.blobs.into_iter();
        remote.extend(resources.into_iter().map(|[family, view]| (family, view)).zip(blobs.by_ref()));
        let own_bands: Vec<[u32; 3]> = serde_json::from_value(header["bands"].clone()).context("a rank's band list")?;
        bands.extend(own_bands.into_iter().map(|[family, view, device]| (family, view, device)).zip(blobs));
        let views: Vec<u32> = serde_json::from_value(header["views"].clone())?;
        let names: Vec<String> = serde_json::from_value(header["devices"].clone())?;
        device_names.extend(names);
        let wall = header["wall_ms_per_frame"].as_f64().unwrap_or(0.0);
        wall_ms = wall_ms.max(wall);
        let first = layout.first(rank);
        let frames_ms: Vec<f64> =
            collector.frames[rank].iter().filter(|s| s.frame >= settings.warmup).map(|s| s.wall_ms).collect();
        ranks.push(serde_json::json!({
            "rank": rank, "host": cluster.hosts[rank], "devices": (first..first + layout.devices[rank]).collect::<Vec<_>>(),
            "views": views, "wall_ms_per_frame": wall, "frame_gpu_ms": header["frame_gpu_ms"],
            "submit_ms_per_frame": frames_ms, "bytes_sent": f.bytes,
        }));
    }
    let json =
        serde_json::json!({ "count": cluster.size(), "timeout_s": settings.rank_timeout.as_secs(), "per_rank": ranks });
    Ok(RankViews { remote, remote_views, bands, plan, device_names, wall_ms, json })
}

/// A camera as the bits of its floats: sent exactly, so every rank renders the same rays.
fn camera_bits(c: &Camera) -> [u32; 12] {
    let f = [c.eye.x, c.eye.y, c.eye.z, c.forward.x, c.forward.y, c.forward.z, c.up.x, c.up.y, c.up.z, c.yfov];
    let mut bits = [0u32; 12];
    for (b, v) in bits.iter_mut().zip(f.into_iter().chain([c.shift.x, c.shift.y])) {
        *b = v.to_bits();
    }
    bits
}

fn camera_of_bits(b: &[u32; 12]) -> Camera {
    let f = b.map(f32::from_bits);
    Camera {
        eye: Vec3::new(f[0], f[1], f[2]),
        forward: Vec3::new(f[3], f[4], f[5]),
        up: Vec3::new(f[6], f[7], f[8]),
        yfov: f[9],
        shift: Vec2::new(f[10], f[11]),
    }
}
