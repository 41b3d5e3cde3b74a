//! Synthetic terrain dataset in the shape of the paper's RougE: procedural scenes of six terrain
//! categories (or indoor rooms and urban street edges), nine views per scene from a robot camera,
//! four lightings and five weathers, with exact depth, normals and labels and roughness from the
//! annotator (spec v1).

pub mod appearance;
pub mod content;
pub mod dataset;
pub mod heightgrid;
pub mod imaging;
pub mod noise;
pub mod objects;
pub mod render;
pub mod sensor;
pub mod surface;
pub mod terrain;

pub use appearance::{Conditions, Lighting, Weather};
pub use content::Content;
pub use dataset::{generate, SynthConfig};
pub use heightgrid::HeightGrid;
pub use render::{render, RenderedFrame, Scene, View};
pub use sensor::{simulate, SensorInput, SensorModel};
pub use surface::Category;
pub use terrain::Terrain;
