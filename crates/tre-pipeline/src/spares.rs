//! Maps handed back by [`Pipeline::recycle`](super::Pipeline::recycle), kept for the next
//! frames, so that a pipeline run frame after frame reuses its buffers instead of allocating
//! (and page-faulting in) fresh megabytes for every map of every frame.
//!
//! What is kept is bounded, so that one huge frame does not pin its memory for good: no buffer
//! over [`MAX_GRID_BYTES`] (glibc's own largest reuse threshold), at most [`MAX_KEPT_BYTES`] in
//! all and [`KEEP`] grids per map type. A frame runs the same with or without spares.

use tre_core::geometry::{Grid, Vec3};

/// Spare grids kept per map type (a frame has at most five of each in use at once).
const KEEP: usize = 8;
/// Largest buffer kept, bytes (a 1280×1024 map of vectors; glibc's largest mmap threshold).
pub(crate) const MAX_GRID_BYTES: usize = 32 << 20;
/// Most bytes kept in all.
pub(crate) const MAX_KEPT_BYTES: usize = 192 << 20;

/// Spare scalar and vector grids, of any size: every stage resizes the grid it takes.
#[derive(Debug, Default)]
pub(crate) struct Spares {
    scalars: Vec<Grid<f64>>,
    vectors: Vec<Grid<Vec3>>,
}

/// A map value type with a shelf of spare grids.
pub(crate) trait Spare: Sized {
    /// The spare grids of this type.
    fn shelf(spares: &mut Spares) -> &mut Vec<Grid<Self>>;
}

impl Spare for f64 {
    fn shelf(spares: &mut Spares) -> &mut Vec<Grid<Self>> {
        &mut spares.scalars
    }
}

impl Spare for Vec3 {
    fn shelf(spares: &mut Spares) -> &mut Vec<Grid<Self>> {
        &mut spares.vectors
    }
}

/// Bytes of `grid`'s buffer.
fn grid_bytes<T>(grid: &Grid<T>) -> usize {
    grid.capacity() * std::mem::size_of::<T>()
}

impl Spares {
    /// A grid to write a map into (empty when none is spare).
    pub(crate) fn take<T: Spare>(&mut self) -> Grid<T> {
        T::shelf(self).pop().unwrap_or_default()
    }

    /// Keeps `grid` for a later [`take`](Self::take), within the bounds.
    pub(crate) fn keep<T: Spare>(&mut self, grid: Grid<T>) {
        let n = grid_bytes(&grid);
        let room = n <= MAX_GRID_BYTES && self.bytes() + n <= MAX_KEPT_BYTES;
        if room && T::shelf(self).len() < KEEP {
            T::shelf(self).push(grid);
        }
    }

    /// Bytes of the buffers kept (at most 2 × [`KEEP`] grids to add up).
    fn bytes(&self) -> usize {
        let scalars = self.scalars.iter().map(grid_bytes);
        scalars.chain(self.vectors.iter().map(grid_bytes)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_grids_up_to_the_limits_and_hands_them_back() {
        let mut spares = Spares::default();
        assert_eq!(spares.take::<f64>().size(), (0, 0));
        for _ in 0..KEEP + 3 {
            spares.keep(Grid::new(4, 3, 1.0));
        }
        let kept = std::iter::from_fn(|| Some(spares.take::<f64>()))
            .take_while(|g| g.size() == (4, 3))
            .count();
        assert_eq!(kept, KEEP);
        assert_eq!(spares.bytes(), 0);
        spares.keep(Grid::new(2, 2, Vec3::zeros()));
        assert_eq!(spares.take::<Vec3>().size(), (2, 2));
        assert_eq!(spares.take::<Vec3>().size(), (0, 0));
    }

    #[test]
    fn keeps_no_huge_buffer_and_bounds_the_total() {
        let mut spares = Spares::default();
        // 4096 × 4096 × 8 bytes = 128 MiB: over the per-buffer limit.
        spares.keep(Grid::new(4096, 4096, 0.0));
        assert_eq!(spares.take::<f64>().size(), (0, 0));
        // 1024 × 1024 vectors = 24 MiB each: eight would be 192 MiB, the total allows seven
        // beside a 16 MiB scalar map.
        spares.keep(Grid::new(2048, 1024, 0.0));
        for _ in 0..8 {
            spares.keep(Grid::new(1024, 1024, Vec3::zeros()));
        }
        assert!(spares.bytes() <= MAX_KEPT_BYTES);
        let vectors = std::iter::from_fn(|| Some(spares.take::<Vec3>()))
            .take_while(|g| g.size() == (1024, 1024))
            .count();
        assert_eq!(vectors, 7);
        assert_eq!(spares.take::<f64>().size(), (2048, 1024));
        assert_eq!(spares.bytes(), 0);
    }
}
