//! Two colours in a checkerboard over uv: cell (i, j) = (⌊u·scale.x⌋, ⌊v·scale.y⌋) is
//! `color0` when i + j is even (so uv (0, 0) is `color0`), else `color1`.
//!
//! ```xml
//! <texture name="albedo" type="checkerboard" scale="16,8" color0="0.08,0.25,0.7" color1="0.9"/>
//! ```

use glam::{Vec2, Vec3};

#[derive(Debug, Clone, PartialEq)]
pub struct Checkerboard {
    pub scale: Vec2,
    pub color0: Vec3,
    pub color1: Vec3,
}

impl Checkerboard {
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        let i = (uv.x * self.scale.x).floor() as i64;
        let j = (uv.y * self.scale.y).floor() as i64;
        if (i + j).rem_euclid(2) == 0 {
            self.color0
        } else {
            self.color1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_alternate() {
        let c = Checkerboard {
            scale: Vec2::new(2.0, 4.0),
            color0: Vec3::ZERO,
            color1: Vec3::ONE,
        };
        assert_eq!(c.eval(Vec2::new(0.1, 0.1)), Vec3::ZERO);
        assert_eq!(c.eval(Vec2::new(0.6, 0.1)), Vec3::ONE);
        assert_eq!(c.eval(Vec2::new(0.6, 0.3)), Vec3::ZERO);
        assert_eq!(c.eval(Vec2::new(-0.1, 0.1)), Vec3::ONE);
    }
}
