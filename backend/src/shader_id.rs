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
