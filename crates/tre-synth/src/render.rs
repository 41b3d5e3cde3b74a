//! Renders one view of a synthetic scene: exact depth, normals and labels from the bilinear
//! height grid, and a shaded RGB image with cast shadows (row-parallel, deterministic).

use image::RgbImage;
use nalgebra::{Matrix3, Rotation3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::appearance::{albedo, shade, sky_radiance, to_srgb8, Conditions, Light, ShadeInput};
use super::heightgrid::HeightGrid;
use super::terrain::Terrain;
use tre_core::geometry::{Grid, Intrinsics, Mounting, Vec3, INVALID_POINT};

/// Most direct lights a frame has.
const MAX_LIGHTS: usize = 4;

/// A camera on the robot: mounting (pitch, height), heading (yaw) and intrinsics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// Pitch below the horizon and height above the ground.
    pub mounting: Mounting,
    /// Heading, radians from +y towards +x.
    pub yaw_rad: f64,
    /// Roll about the optical axis, radians (the camera frame turned about its z axis before
    /// the mounting's pitch); 0 for a level camera.
    #[serde(default)]
    pub roll_rad: f64,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl View {
    /// Rotation from the camera frame to the world frame (gravity frame turned by the yaw).
    pub fn world_from_cam(&self) -> Matrix3<f64> {
        *Rotation3::from_axis_angle(&Vec3::z_axis(), -self.yaw_rad).matrix()
            * self.mounting.gravity_from_cam()
            * Rotation3::from_axis_angle(&Vec3::z_axis(), self.roll_rad).matrix()
    }

    /// Camera centre in the world frame.
    pub fn centre(&self) -> Vec3 {
        Vec3::new(0.0, 0.0, self.mounting.height_m)
    }
}

/// A scene ready to render: its terrain and the grid sampled from it.
pub struct Scene {
    /// The terrain (regions, categories).
    pub terrain: Terrain,
    /// The rendered surface.
    pub grid: HeightGrid,
}

/// What a view of a scene yields.
pub struct RenderedFrame {
    /// Depth (camera z), metres; 0 where no ground is seen.
    pub depth_m: Grid<f64>,
    /// Unit normals in the camera frame, oriented towards the camera; NaN where none.
    pub normals_cam: Grid<Vec3>,
    /// Semantic labels (category; 0 = void).
    pub labels: Grid<u32>,
    /// The shaded image.
    pub rgb: RgbImage,
}

/// Everything one pixel yields.
#[derive(Clone, Copy)]
struct Pixel {
    depth: f64,
    normal: Vec3,
    label: u32,
    rgb: [u8; 3],
}

/// Renders `view` of `scene` under `conditions`.
pub fn render(scene: &Scene, view: &View, conditions: &Conditions) -> RenderedFrame {
    let (w, h) = (view.width, view.height);
    let rot = view.world_from_cam();
    let lights = conditions.lights(&view.centre());
    let mut pixels = vec![
        Pixel {
            depth: 0.0,
            normal: INVALID_POINT,
            label: 0,
            rgb: [0; 3]
        };
        w * h
    ];
    pixels
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(v, row)| {
            for (u, px) in row.iter_mut().enumerate() {
                *px = render_pixel(scene, view, &rot, &lights, conditions, u, v);
            }
        });
    let rgb = RgbImage::from_fn(w as u32, h as u32, |u, v| {
        image::Rgb(pixels[v as usize * w + u as usize].rgb)
    });
    let at = |u: usize, v: usize| &pixels[v * w + u];
    RenderedFrame {
        depth_m: Grid::from_fn(w, h, |u, v| at(u, v).depth),
        normals_cam: Grid::from_fn(w, h, |u, v| at(u, v).normal),
        labels: Grid::from_fn(w, h, |u, v| at(u, v).label),
        rgb,
    }
}

fn render_pixel(
    scene: &Scene,
    view: &View,
    rot: &Matrix3<f64>,
    lights: &[Light],
    conditions: &Conditions,
    u: usize,
    v: usize,
) -> Pixel {
    let ray_cam = view.intrinsics.back_project(u as f64, v as f64, 1.0);
    let dir = rot * ray_cam.normalize();
    let origin = view.centre();
    let Some(t) = scene.grid.intersect(&origin, &dir, 60.0) else {
        return Pixel {
            depth: 0.0,
            normal: INVALID_POINT,
            label: 0,
            rgb: to_srgb8(sky_radiance(&dir, conditions)),
        };
    };
    let point = origin + dir * t;
    let normal = scene
        .grid
        .normal(point.x, point.y)
        .expect("hit points lie on the grid; this is a bug");
    // An object's surface stands in as a region, with the point in the object's frame.
    let object_surface;
    let (region, local) = match scene.grid.owner(point.x, point.y) {
        None => (scene.terrain.region_at(point.x, point.y), point),
        Some(k) => {
            object_surface = scene.terrain.objects[k].surface(&point);
            (&object_surface.0, object_surface.1)
        }
    };
    let mut visible = [1.0; MAX_LIGHTS];
    for (vis, l) in visible.iter_mut().zip(lights) {
        *vis = visibility(&scene.grid, &point, &normal, l);
    }
    let colour = shade(&ShadeInput {
        albedo: albedo(region, &local, &normal, conditions.weather),
        normal,
        point,
        to_camera: -dir,
        distance_m: t,
        lights,
        visibility: &visible[..lights.len().min(MAX_LIGHTS)],
        conditions,
    });
    Pixel {
        depth: t / ray_cam.norm(),
        normal: rot.transpose() * normal,
        label: u32::from(region.category.label()),
        rgb: to_srgb8(colour),
    }
}

/// 1 where `light` reaches `point`, 0 where the terrain casts a shadow on it.
fn visibility(grid: &HeightGrid, point: &Vec3, normal: &Vec3, light: &Light) -> f64 {
    let start = point + normal * 1e-3;
    let (dir, dist) = match *light {
        Light::Sun { dir, .. } => (dir, 60.0),
        Light::Lamp { pos, .. } => {
            let v = pos - start;
            (v.normalize(), v.norm())
        }
    };
    if normal.dot(&dir) <= 0.0 {
        return 0.0;
    }
    if grid.intersect(&start, &dir, dist).is_some() {
        0.0
    } else {
        1.0
    }
}
