//! Image-space passes: typed per-pixel buffers for whole-image integrators (`ratio`'s
//! denoiser today, sheared filtering next), so that a pass is a plain function over
//! `ImageBuffer`s instead of hand-indexed film channels.

use rayon::prelude::*;

/// A row-major `width × height` image with one `T` per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageBuffer<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T> ImageBuffer<T> {
    /// `None` when `data` does not hold `width × height` pixels.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Option<ImageBuffer<T>> {
        (data.len() == width * height).then_some(ImageBuffer { width, height, data })
    }

    /// Pixel `i` (row-major index) from `f(i)`.
    pub fn from_fn(width: usize, height: usize, f: impl FnMut(usize) -> T) -> ImageBuffer<T> {
        ImageBuffer { width, height, data: (0..width * height).map(f).collect() }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Same width and height as `o`.
    pub fn same_size<U>(&self, o: &ImageBuffer<U>) -> bool {
        self.width == o.width && self.height == o.height
    }

    /// The pixels, row-major.
    pub fn pixels(&self) -> &[T] {
        &self.data
    }

    pub fn at(&self, x: usize, y: usize) -> &T {
        &self.data[y * self.width + x]
    }

    /// A new image of `f` applied to every pixel.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> ImageBuffer<U> {
        ImageBuffer { width: self.width, height: self.height, data: self.data.iter().map(f).collect() }
    }
}

impl<T: Clone> ImageBuffer<T> {
    pub fn filled(width: usize, height: usize, value: T) -> ImageBuffer<T> {
        ImageBuffer { width, height, data: vec![value; width * height] }
    }
}

impl<T: Send> ImageBuffer<T> {
    /// A new image whose row `y` is `row(y)` (which must return `width` pixels), rows computed
    /// in parallel and assembled in order: the result does not depend on the thread count.
    pub fn from_rows_par(width: usize, height: usize, row: impl Fn(usize) -> Vec<T> + Sync) -> ImageBuffer<T> {
        let rows: Vec<Vec<T>> = (0..height).into_par_iter().map(&row).collect();
        let mut data = Vec::with_capacity(width * height);
        for r in rows {
            assert_eq!(r.len(), width, "a row of {} pixels in an image {width} wide", r.len());
            data.extend(r);
        }
        ImageBuffer { width, height, data }
    }
}

impl<T> std::ops::Index<usize> for ImageBuffer<T> {
    type Output = T;
    fn index(&self, i: usize) -> &T {
        &self.data[i]
    }
}

impl<T> std::ops::IndexMut<usize> for ImageBuffer<T> {
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.data[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_row_major_and_rows_keep_their_order() {
        let img = ImageBuffer::from_fn(3, 2, |i| i as u32);
        assert_eq!(*img.at(2, 0), 2);
        assert_eq!(*img.at(0, 1), 3);
        assert_eq!(img[5], 5);
        let par = ImageBuffer::from_rows_par(3, 2, |y| (0..3).map(|x| (y * 3 + x) as u32).collect());
        assert_eq!(par, img);
        let doubled = img.map(|v| v * 2);
        assert_eq!(doubled.pixels(), &[0, 2, 4, 6, 8, 10]);
        assert!(doubled.same_size(&img) && !doubled.same_size(&ImageBuffer::filled(2, 3, 0u8)));
        assert!(ImageBuffer::from_vec(2, 2, vec![0; 3]).is_none());
        assert_eq!(ImageBuffer::from_vec(2, 2, vec![1; 4]), Some(ImageBuffer::filled(2, 2, 1)));
    }
}
