//! `parallax._native`: the Python module's bindings to the `parallax` library. Every command
//! runs in-process exactly as the binary runs it ([`parallax::run_command`]), so a run file
//! gives the same views from Python as from the command line; what a command writes (EXRs, PNGs,
//! render.json, DOT) is read back here into NumPy arrays and Python values. The API people use
//! is the Python package around this (`python/python/parallax/__init__.py`).

use std::path::Path;
use std::sync::Mutex;

use numpy::{IntoPyArray, PyArray3, ndarray::Array3};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    _native,
    ParallaxError,
    PyException,
    "A command failed: the message is the one `parallax` prints after `error: ` (the CLI exits with 1)."
);
create_exception!(
    _native,
    UsageError,
    ParallaxError,
    "Settings no run could use, or that do not go together (the CLI exits with 2)."
);

/// One command at a time: the outputs a failed command removes are tracked for the whole
/// process, so two commands at once would remove each other's.
static COMMAND: Mutex<()> = Mutex::new(());

/// Runs `parallax WORDS…` in this process (without the program's name); raises `UsageError`
/// or `ParallaxError` with the CLI's message. The interpreter's other threads run meanwhile.
#[pyfunction]
fn run(py: Python<'_>, words: Vec<String>) -> PyResult<()> {
    let outcome = py.detach(|| {
        let _one = COMMAND.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        parallax::run_command(words)
    });
    outcome.map_err(|failure| match failure.usage {
        true => UsageError::new_err(failure.message),
        false => ParallaxError::new_err(failure.message),
    })
}

/// The flags of a run file's settings, given as JSON (`{"spp": 4, "still": true}` →
/// `["--spp=4", "--still"]`), as `render --config` reads a run file.
#[pyfunction]
fn run_file_flags(origin: &str, settings_json: &str) -> PyResult<Vec<String>> {
    let value: serde_json::Value =
        serde_json::from_str(settings_json).map_err(|e| ParallaxError::new_err(format!("{origin}: {e}")))?;
    let Some(table) = value.as_object() else {
        return Err(ParallaxError::new_err(format!("{origin}: expected a table of settings")));
    };
    parallax::run_file_flags(origin, table).map_err(|e| UsageError::new_err(format!("{e:#}")))
}

/// The named float channels of an EXR's first layer as an array of height × width × channels
/// (e.g. `["R", "G", "B"]`, or a layer such as `["depth.Z"]`).
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: &str, channels: Vec<String>) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let names: Vec<&str> = channels.iter().map(String::as_str).collect();
    let (width, height, planes) = py
        .detach(|| parallax_scene::output::read_exr_channels(Path::new(path), &names))
        .map_err(|e| ParallaxError::new_err(e.to_string()))?;
    let pixels: Vec<f32> = (0..width * height).flat_map(|i| planes.iter().map(move |plane| plane[i])).collect();
    let array = Array3::from_shape_vec((height, width, names.len()), pixels).expect("one value per channel and pixel");
    Ok(array.into_pyarray(py))
}

/// A PNG as an array of height × width × channels of uint8 (its own channels: 1 to 4).
#[pyfunction]
fn read_png<'py>(py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let image =
        py.detach(|| image::open(path)).map_err(|e| ParallaxError::new_err(format!("cannot read {path}: {e}")))?;
    let channels = image.color().channel_count() as usize;
    let (width, height) = (image.width() as usize, image.height() as usize);
    let bytes = match channels {
        1 => image.into_luma8().into_raw(),
        2 => image.into_luma_alpha8().into_raw(),
        3 => image.into_rgb8().into_raw(),
        _ => image.into_rgba8().into_raw(),
    };
    let array = Array3::from_shape_vec((height, width, channels.min(4)), bytes).expect("one byte per channel");
    Ok(array.into_pyarray(py))
}

/// Loads `--scene SPEC` as the commands do and describes it: name, triangle, material, light
/// and camera counts, bounds, and whether it has any light of its own.
#[pyfunction]
fn load_scene<'py>(py: Python<'py>, spec: &str, allow_outside_files: bool) -> PyResult<Bound<'py, PyDict>> {
    let scene = py
        .detach(|| parallax::load_scene(spec, allow_outside_files))
        .map_err(|e| ParallaxError::new_err(format!("{e:#}")))?;
    let bounds = scene.bounds();
    let info = PyDict::new(py);
    info.set_item("name", &scene.name)?;
    info.set_item("triangles", scene.triangle_count())?;
    info.set_item("materials", scene.materials.len())?;
    info.set_item("lights", scene.lights.len())?;
    info.set_item("cameras", scene.cameras.len())?;
    info.set_item("animated_camera", scene.camera_animation.is_some())?;
    info.set_item("bounds_min", bounds.min.to_array().to_vec())?;
    info.set_item("bounds_max", bounds.max.to_array().to_vec())?;
    info.set_item("has_light", scene.has_light())?;
    Ok(info)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ParallaxError", m.py().get_type::<ParallaxError>())?;
    m.add("UsageError", m.py().get_type::<UsageError>())?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(run_file_flags, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(read_png, m)?)?;
    m.add_function(wrap_pyfunction!(load_scene, m)?)?;
    Ok(())
}
