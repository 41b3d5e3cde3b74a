//! Maps handed back by [`Pipeline::recycle`](super::Pipeline::recycle), kept for the next
//! frames, so that a pipeline run frame after frame reuses its buffers instead of allocating
//! (and page-faulting in) fresh megabytes for every map of every frame.

use crate::geometry::{Grid, Vec3};

/// Spare grids kept per map type (a frame uses at most six of each).
const KEEP: usize = 8;

/// Spare scalar and vector grids, of any size: every stage resizes the grid it takes.
#[derive(Debug, Default)]
pub(crate) struct Spares {
    scalars: Vec<Grid<f64>>,
    vectors: Vec<Grid<Vec3>>,
}

impl Spares {
    /// A scalar grid to write a map into (empty when none is spare).
    pub(crate) fn scalar(&mut self) -> Grid<f64> {
        self.scalars.pop().unwrap_or_default()
    }

    /// A vector grid to write a map into (empty when none is spare).
    pub(crate) fn vector(&mut self) -> Grid<Vec3> {
        self.vectors.pop().unwrap_or_default()
    }

    /// Keeps `grid` for a later [`scalar`](Self::scalar).
    pub(crate) fn keep_scalar(&mut self, grid: Grid<f64>) {
        if self.scalars.len() < KEEP {
            self.scalars.push(grid);
        }
    }

    /// Keeps `grid` for a later [`vector`](Self::vector).
    pub(crate) fn keep_vector(&mut self, grid: Grid<Vec3>) {
        if self.vectors.len() < KEEP {
            self.vectors.push(grid);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_grids_up_to_the_limit_and_hands_them_back() {
        let mut spares = Spares::default();
        assert_eq!(spares.scalar().size(), (0, 0));
        for _ in 0..KEEP + 3 {
            spares.keep_scalar(Grid::new(4, 3, 1.0));
        }
        let kept = std::iter::from_fn(|| Some(spares.scalar()))
            .take_while(|g| g.size() == (4, 3))
            .count();
        assert_eq!(kept, KEEP);
        spares.keep_vector(Grid::new(2, 2, Vec3::zeros()));
        assert_eq!(spares.vector().size(), (2, 2));
        assert_eq!(spares.vector().size(), (0, 0));
    }
}
