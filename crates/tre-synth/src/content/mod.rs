//! Scene families of `tre synth --content`: the paper's natural terrain, indoor rooms (tile,
//! wood and carpet floors, walls with a doorway and its sill, cables, boxes, furniture-like
//! blocks, stairs up or down) and urban street edges (asphalt road, paved sidewalk, curb, kerb
//! ramp, drains, posts). Each layout is drawn from the dataset seed and the scene index.

mod layout;
mod room;
mod street;

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::surface::Category;
use super::terrain::Terrain;
use tre_core::geometry::hash::splitmix64;

pub use room::indoor;
pub use street::urban;

/// What the scenes of a dataset show (the switch of `tre synth --content`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Content {
    /// The paper's six natural categories as Voronoi regions (the default; unchanged output).
    #[default]
    Natural,
    /// Rooms: floors, walls, a doorway with its sill, cables, boxes, furniture, stairs.
    Indoor,
    /// Street edges: road, sidewalk, curb, kerb ramp, drains, posts.
    Urban,
    /// Each scene draws one of the three above, uniformly.
    Mixed,
}

impl Content {
    /// Every content switch.
    pub const ALL: [Self; 4] = [Self::Natural, Self::Indoor, Self::Urban, Self::Mixed];

    /// The switch's name, as serde writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Natural => "natural",
            Self::Indoor => "indoor",
            Self::Urban => "urban",
            Self::Mixed => "mixed",
        }
    }

    /// The names, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// True for the default, natural content (whose settings are left out of `dataset.json` so
    /// that natural datasets keep their bytes).
    pub fn is_natural(&self) -> bool {
        *self == Self::Natural
    }

    /// The family of scene `scene` of a dataset seeded with `seed`: this content itself, or for
    /// `mixed` one of natural, indoor and urban drawn from the seed and the scene.
    pub fn family(self, seed: u64, scene: u64) -> Self {
        if self != Self::Mixed {
            return self;
        }
        let h = splitmix64(splitmix64(seed ^ 0xC0_47E4) ^ scene.wrapping_mul(0x9E37_79B9));
        [Self::Natural, Self::Indoor, Self::Urban][(h % 3) as usize]
    }

    /// The labels a dataset of this content lists: the six natural ones for natural content
    /// (as before the other families existed), every label otherwise.
    pub fn labels(self) -> &'static [Category] {
        match self {
            Self::Natural => &Category::NATURAL,
            _ => Category::ALL,
        }
    }

    /// The terrain of scene `scene` (a family, not `mixed`), with content within `reach_m` of
    /// the robot.
    pub fn terrain(self, seed: u64, scene: u64, reach_m: f64) -> Terrain {
        match self.family(seed, scene) {
            Self::Indoor => indoor(seed, scene, reach_m),
            Self::Urban => urban(seed, scene, reach_m),
            _ => Terrain::random(seed, scene, reach_m),
        }
    }
}

impl fmt::Display for Content {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`Content`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown content {name:?}: one of {}", Content::names())]
pub struct UnknownContent {
    /// The name given.
    pub name: String,
}

impl FromStr for Content {
    type Err = UnknownContent;

    /// A content switch by name (case does not matter).
    ///
    /// ```
    /// use tre_synth::content::Content;
    /// assert_eq!("Indoor".parse(), Ok(Content::Indoor));
    /// let unknown = "forest".parse::<Content>().unwrap_err();
    /// assert_eq!(
    ///     unknown.to_string(),
    ///     "unknown content \"forest\": one of natural, indoor, urban, mixed"
    /// );
    /// ```
    fn from_str(s: &str) -> Result<Self, UnknownContent> {
        let key = s.trim().to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|c| c.name() == key)
            .ok_or_else(|| UnknownContent { name: s.to_owned() })
    }
}
