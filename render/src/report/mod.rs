//! What a render leaves beside its views: render.json's parts (stage times, the settings the
//! pixels depend on, start-up steps), the pictures (view PNGs, contact sheet, quilt, wiggle) and
//! viewer.html.

pub mod images;
pub mod pictures;
pub mod setup;
pub mod stages;
pub mod startup;
pub mod viewer;
