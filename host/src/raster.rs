//! A plain row-major 2-D array: images, phase maps, masks, depth maps.

/// A `width x height` grid of values, row-major, origin top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster<T> {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width * height` values, row after row.
    pub data: Vec<T>,
}

impl<T: Clone> Raster<T> {
    /// A raster filled with one value.
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }
}

impl<T> Raster<T> {
    /// Wraps existing data; `None` when its length is not `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Option<Self> {
        (data.len() == width * height).then_some(Self {
            width,
            height,
            data,
        })
    }

    /// Builds a raster from a function of `(x, y)`.
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

    /// The value at column `x`, row `y` (panics outside, like slice indexing).
    pub fn at(&self, x: usize, y: usize) -> &T {
        &self.data[y * self.width + x]
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the raster has no pixels.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// The 4-neighbours of pixel `i` (row-major) of a `w` x `h` image, left,
/// right, up, down; `None` past a border.
pub(crate) fn neighbours4(i: usize, w: usize, h: usize) -> [Option<usize>; 4] {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn from_fn_is_row_major() {
        let r = Raster::from_fn(3, 2, |x, y| x + 10 * y);
        assert_eq!(r.data, vec![0, 1, 2, 10, 11, 12]);
        assert_eq!(*r.at(2, 1), 12);
        assert!(Raster::from_vec(2, 2, vec![0u8; 3]).is_none());
    }
}
