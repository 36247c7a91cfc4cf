//! Shaders named at compile time: the id a crate's generated bindings declare for each of its
//! shaders ([`crate::shader_bindings!`]), typed by the shader's push-constant block, so that
//! handing a dispatch another block's struct is a type error, not a layout check at run time.

use std::marker::PhantomData;

/// A shader of a [`crate::ShaderLibrary`], by the name the library holds it under, whose
/// push constants are a `P`. Generated, one constant per shader:
/// `pub const TONEMAP: Shader<TonemapPush> = Shader::new("tonemap");`. A dispatch takes the id
/// and a `&P` of the same `P` (as `dispatch` below does, like [`crate::Recorder::dispatch`]):
///
/// ```
/// use parallax_backend::{Shader, ShaderName};
/// fn dispatch<P>(shader: impl ShaderName<P>, _push: &P) -> String {
///     shader.shader_name().to_string()
/// }
/// const FILL: Shader<[u32; 2]> = Shader::new("fill");
/// assert_eq!(dispatch(FILL, &[1, 2]), "fill");
/// assert_eq!(dispatch("added_at_run_time", &1.0f32), "added_at_run_time"); // a name takes any P
/// ```
///
/// and another block's struct does not compile:
///
/// ```compile_fail
/// use parallax_backend::{Shader, ShaderName};
/// fn dispatch<P>(shader: impl ShaderName<P>, _push: &P) {}
/// const FILL: Shader<[u32; 2]> = Shader::new("fill");
/// dispatch(FILL, &1.0f32);
/// ```
pub struct Shader<P> {
    name: &'static str,
    push: PhantomData<fn(&P)>,
}

impl<P> Shader<P> {
    pub const fn new(name: &'static str) -> Self {
        Shader { name, push: PhantomData }
    }

    /// The name the library holds the shader under (a compute shader's file stem, a graphics
    /// stage's file name).
    pub const fn name(self) -> &'static str {
        self.name
    }
}

// Not derived: a derive would demand `P: Clone`, and the id copies whatever `P` is.
impl<P> Clone for Shader<P> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<P> Copy for Shader<P> {}

impl<P> std::fmt::Debug for Shader<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Shader({:?})", self.name)
    }
}

/// What a dispatch names its shader by: a generated [`Shader`] id, whose block type must be the
/// dispatch's `P`, or a name (a shader added at run time with
/// [`crate::ShaderLibrary::with_spirv`]), whose block is checked against `P` when the pipeline is
/// bound.
pub trait ShaderName<P> {
    fn shader_name(&self) -> &str;
}

impl<P> ShaderName<P> for Shader<P> {
    fn shader_name(&self) -> &str {
        self.name
    }
}

impl<P> ShaderName<P> for &str {
    fn shader_name(&self) -> &str {
        self
    }
}

/// The block type of a generated graphics-stage id whose stage declares no push constants
/// (`Shader<NoPushBlock>`): in a draw it takes the block of the other stage ([`DrawStage`]).
/// It is no [`crate::PushConstants`], so no dispatch or draw pushes one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoPushBlock {}

/// What a [`crate::Draw`] names each of its stages by, for a draw whose push constants are a
/// `P`: a generated id typed by `P` (`gbuffer_raster.vert` and `.frag` both declare
/// `GbufferRasterPush`), a generated id of a stage without a block (`Shader<NoPushBlock>`),
/// which takes any `P`, or a name (a stage added at run time), whose block is checked against
/// `P` when the pipeline is bound:
///
/// ```
/// use parallax_backend::{DrawStage, NoPushBlock, PassParams, Shader};
/// fn draw<P>(vertex: impl DrawStage<P>, fragment: impl DrawStage<P>, _push: &P) -> String {
///     format!("{} {}", vertex.stage_name(), fragment.stage_name())
/// }
/// const VERT: Shader<NoPushBlock> = Shader::new("demo.vert");
/// const FRAG: Shader<PassParams> = Shader::new("demo.frag");
/// let push = PassParams::default();
/// assert_eq!(draw(VERT, FRAG, &push), "demo.vert demo.frag");
/// assert_eq!(draw("added.vert", FRAG, &push), "added.vert demo.frag");
/// ```
///
/// and another block's struct does not compile:
///
/// ```compile_fail
/// use parallax_backend::{DrawStage, NoPushBlock, PassParams, Shader};
/// fn draw<P>(vertex: impl DrawStage<P>, fragment: impl DrawStage<P>, _push: &P) {}
/// const VERT: Shader<NoPushBlock> = Shader::new("demo.vert");
/// const FRAG: Shader<PassParams> = Shader::new("demo.frag");
/// draw(VERT, FRAG, &());
/// ```
pub trait DrawStage<P> {
    fn stage_name(&self) -> &str;
}

impl<P: crate::PushConstants> DrawStage<P> for Shader<P> {
    fn stage_name(&self) -> &str {
        self.name
    }
}

impl<P: crate::PushConstants> DrawStage<P> for Shader<NoPushBlock> {
    fn stage_name(&self) -> &str {
        self.name
    }
}

impl<P> DrawStage<P> for &str {
    fn stage_name(&self) -> &str {
        self
    }
}

/// Declares, in the calling module, the shader bindings that parallax-glsl wrote from the
/// crate's compiled shaders (`parallax_glsl::BINDINGS_FILE`): a `#[repr(C)]` struct per
/// push-constant block, implementing [`crate::PushConstants`], and a [`Shader`] id per shader.
/// The crate's build.rs compiles its shaders with parallax-glsl; the crate depends on
/// parallax-backend by that name.
#[macro_export]
macro_rules! shader_bindings {
    () => {
        // parallax_glsl::BINDINGS_FILE
        include!(concat!(env!("OUT_DIR"), "/shader_bindings.rs"));
    };
}
