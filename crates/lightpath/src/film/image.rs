//! A linear RGB floating-point image: what the film develops into, what textures and
//! reference images are read into.

use glam::Vec3;

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// A black image of the given size.
    pub fn new(width: u32, height: u32) -> Self {
        Image {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    #[inline]
    pub fn set(&mut self, x: u32, y: u32, value: Vec3) {
        let w = self.width as usize;
        self.pixels[y as usize * w + x as usize] = value;
    }
}
