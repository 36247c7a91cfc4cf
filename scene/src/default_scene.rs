//! The embedded default scene: what `parallax render` shows when no scene file is given.
//!
//! Small (under 2k triangles) and built to exercise reprojection: pillars and boxes at several
//! depths in front of a back wall, so that views shifted sideways uncover different parts of the
//! background (disocclusions); a diffuse floor and walls, glossy dielectric and metal objects
//! (which reprojection reuses only within its view-dependence bound), an emissive ceiling
//! panel, a gradient sky and a low sun.

use glam::{Vec2, Vec3};

use crate::builder::SceneBuilder;
use crate::camera::Camera;
use crate::model::{Material, Scene, Sky, Sun};

/// Builds the default scene. Units are metres; +Y is up; the camera looks down -Z.
pub fn default_scene() -> Scene {
    let mut b = SceneBuilder::new("default");
    let floor = b.material(Material::diffuse("floor", Vec3::new(0.55, 0.55, 0.5)));
    let wall = b.material(Material::diffuse("wall", Vec3::new(0.7, 0.68, 0.62)));
    let red = b.material(Material::diffuse("red", Vec3::new(0.6, 0.08, 0.06)));
    let green = b.material(Material::diffuse("green", Vec3::new(0.12, 0.45, 0.1)));
    let blue_gloss = b.material(Material::glossy("blue gloss", Vec3::new(0.1, 0.2, 0.6), 0.0, 0.25));
    let gold = b.material(Material::glossy("gold", Vec3::new(1.0, 0.78, 0.34), 1.0, 0.3));
    let chrome = b.material(Material::glossy("chrome", Vec3::new(0.9, 0.9, 0.9), 1.0, 0.05));
    let lamp = b.material(Material::emitter("lamp", Vec3::new(12.0, 11.0, 9.0)));

    // Floor (8 x 10 m) and a back wall with a side wall, open towards the camera and the sky.
    b.quad(Vec3::new(-4.0, 0.0, 4.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -10.0), floor);
    b.quad(Vec3::new(-4.0, 0.0, -6.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0), wall);
    b.quad(Vec3::new(-4.0, 0.0, 4.0), Vec3::new(0.0, 0.0, -10.0), Vec3::new(0.0, 4.0, 0.0), wall);

    // Occluders at several depths (z from +1.5 near the camera to -4.5 near the wall).
    b.cuboid(Vec3::new(-1.2, 0.9, 1.5), Vec3::new(0.15, 0.9, 0.15), 0.0, red);
    b.cuboid(Vec3::new(1.4, 0.5, 0.5), Vec3::new(0.5, 0.5, 0.5), 0.4, green);
    b.cuboid(Vec3::new(-0.3, 1.25, -1.5), Vec3::new(0.2, 1.25, 0.2), 0.0, wall);
    b.cuboid(Vec3::new(2.2, 1.6, -3.0), Vec3::new(0.3, 1.6, 0.3), 0.2, red);
    b.cuboid(Vec3::new(-2.4, 0.6, -4.5), Vec3::new(0.8, 0.6, 0.6), -0.3, green);
    b.sphere(Vec3::new(0.4, 0.45, 0.2), 0.45, 2, blue_gloss);
    b.sphere(Vec3::new(-1.6, 0.35, -0.6), 0.35, 2, gold);
    b.sphere(Vec3::new(1.0, 0.6, -2.4), 0.6, 2, chrome);

    // Emissive panel under a thin roof slab, facing down.
    b.quad(Vec3::new(-1.0, 3.2, -1.5), Vec3::new(0.0, 0.0, -1.5), Vec3::new(2.0, 0.0, 0.0), lamp);

    b.camera(Camera {
        eye: Vec3::new(0.0, 1.4, 5.5),
        forward: Vec3::new(0.0, -0.12, -1.0).normalize(),
        up: Vec3::Y,
        yfov: 0.75,
        shift: Vec2::ZERO,
    });
    let mut scene = b.build();
    (scene.sky, scene.sun) = default_lighting();
    scene
}

/// The default scene's lighting, a gradient sky and a low sun, for scenes built in code that
/// should be lit like it.
pub fn default_lighting() -> (Option<Sky>, Option<Sun>) {
    let sky = Sky::Gradient {
        zenith: Vec3::new(0.15, 0.25, 0.5),
        horizon: Vec3::new(0.45, 0.5, 0.55),
        ground: Vec3::new(0.15, 0.13, 0.1),
    };
    let sun = Sun {
        to_sun: Vec3::new(-0.5, 0.6, 0.45).normalize(),
        irradiance: Vec3::new(1.3, 1.2, 1.1),
        angular_radius: 0.02,
    };
    (Some(sky), Some(sun))
}

/// The white-furnace scene: a sphere and a box of albedo-1 Lambert material close together
/// under a uniform sky of radiance 1 and no other light, so every pixel (object or sky) has
/// expected value 1. What the CPU and GPU energy-conservation tests render.
pub fn white_furnace_scene() -> Scene {
    let mut b = SceneBuilder::new("furnace");
    let white = b.material(Material::diffuse("white", Vec3::ONE));
    b.sphere(Vec3::new(-0.55, 0.0, 0.0), 0.5, 3, white);
    b.cuboid(Vec3::new(0.55, 0.0, 0.0), Vec3::splat(0.45), 0.5, white);
    let mut scene = b.build();
    scene.sky = Some(Sky::Constant(Vec3::ONE));
    scene
}
