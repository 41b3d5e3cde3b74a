//! `Grid<T>`: a row-major 2-D buffer of per-pixel values, the common currency of the geometry kernels.

use super::GeometryError;

/// The 8-neighbourhood of a cell, `(dx, dy)`: row above, same row, row below.
pub const NEIGHBOURS_8: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// A row-major `width × height` buffer of per-pixel values.
///
/// ```
/// use tre_core::geometry::Grid;
/// let mut g = Grid::new(3, 2, 0u8);
/// g[(2, 1)] = 7;
/// assert_eq!(g.get(2, 1), Some(&7));
/// assert_eq!(g.row(1), &[0, 0, 7]);
/// ```
#[derive(Debug, PartialEq)]
pub struct Grid<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Clone> Clone for Grid<T> {
    fn clone(&self) -> Self {
        Self {
            width: self.width,
            height: self.height,
            data: self.data.clone(),
        }
    }

    /// Copies `source` into this grid's buffer, which it keeps (allocating only to grow).
    fn clone_from(&mut self, source: &Self) {
        self.width = source.width;
        self.height = source.height;
        self.data.clone_from(&source.data);
    }
}

impl<T> Default for Grid<T> {
    /// An empty 0×0 grid (a buffer not sized yet).
    fn default() -> Self {
        Self {
            width: 0,
            height: 0,
            data: Vec::new(),
        }
    }
}

impl<T: Clone> Grid<T> {
    /// A grid filled with `value`.
    pub fn new(width: usize, height: usize, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// Makes this grid `width × height` and fills it with `value`, keeping its buffer: a grid
    /// reused from frame to frame allocates only when it grows past its largest size so far.
    ///
    /// ```
    /// use tre_core::geometry::Grid;
    /// let mut g = Grid::new(4, 4, 1.0);
    /// let buffer = g.as_slice().as_ptr();
    /// g.reset(3, 2, f64::NAN);
    /// assert_eq!(g.size(), (3, 2));
    /// assert!(g.as_slice().iter().all(|v| v.is_nan()));
    /// assert_eq!(g.as_slice().as_ptr(), buffer);
    /// ```
    pub fn reset(&mut self, width: usize, height: usize, value: T) {
        self.data.clear();
        self.data.resize(width * height, value);
        self.width = width;
        self.height = height;
    }
}

impl<T> Grid<T> {
    /// Wraps `data` (row-major) as a `width × height` grid; its length must match.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Result<Self, GeometryError> {
        if data.len() != width * height {
            return Err(GeometryError::BufferSize {
                width,
                height,
                len: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Builds a grid by calling `f(x, y)` for every pixel.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Builds a grid by calling `f(x, y)` for every pixel, rows in parallel.
    pub fn par_from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> T + Sync) -> Self
    where
        T: Send,
    {
        use rayon::prelude::*;
        let data = (0..width * height)
            .into_par_iter()
            .map(|i| f(i % width, i / width))
            .collect();
        Self {
            width,
            height,
            data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The value at `(x, y)`, or `None` outside the grid.
    pub fn get(&self, x: usize, y: usize) -> Option<&T> {
        (x < self.width && y < self.height).then(|| &self.data[y * self.width + x])
    }

    /// Row `y` as a slice.
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// All values, row-major.
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    /// All values, row-major, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// The rows as mutable slices with their `y`, for filling in parallel.
    ///
    /// ```
    /// use rayon::prelude::*;
    /// use tre_core::geometry::Grid;
    /// let mut g = Grid::new(3, 2, 0usize);
    /// g.par_rows_mut().for_each(|(y, row)| row.iter_mut().enumerate().for_each(|(x, v)| *v = x + 10 * y));
    /// assert_eq!(g.row(1), &[10, 11, 12]);
    /// ```
    pub fn par_rows_mut(
        &mut self,
    ) -> impl rayon::iter::IndexedParallelIterator<Item = (usize, &mut [T])> + '_
    where
        T: Send,
    {
        use rayon::prelude::*;
        self.data.par_chunks_mut(self.width.max(1)).enumerate()
    }

    /// Values the grid's buffer holds room for (at least `width × height`; more after a
    /// [`reset`](Self::reset) to a smaller size).
    pub fn capacity(&self) -> usize {
        self.data.capacity()
    }

    /// Consumes the grid and returns its row-major buffer.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// Applies `f` to every value, keeping the shape.
    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Grid<U> {
        Grid {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

impl<T> std::ops::Index<(usize, usize)> for Grid<T> {
    type Output = T;
    fn index(&self, (x, y): (usize, usize)) -> &T {
        &self.data[y * self.width + x]
    }
}

impl<T> std::ops::IndexMut<(usize, usize)> for Grid<T> {
    fn index_mut(&mut self, (x, y): (usize, usize)) -> &mut T {
        &mut self.data[y * self.width + x]
    }
}
