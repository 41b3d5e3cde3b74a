//! Synthetic terrain dataset in the shape of the paper's RougE: procedural scenes of six terrain
//! categories (or indoor rooms and urban street edges), nine views per scene from a robot camera,
//! four lightings and five weathers, with exact depth, normals and labels and roughness from the
//! annotator (spec v1).

mod appearance;
#[cfg(feature = "cli")]
mod cli;
pub mod content;
pub mod dataset;
mod heightgrid;
pub mod imaging;
pub mod noise;
pub mod objects;
mod render;
pub mod sensor;
pub mod surface;
mod terrain;

pub use appearance::{Conditions, Lighting, Weather};
#[cfg(feature = "cli")]
pub use cli::SynthArgs;
pub use heightgrid::HeightGrid;
pub use render::{render, RenderedFrame, Scene, View};
pub use terrain::Terrain;
