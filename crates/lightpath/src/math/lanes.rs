//! Sixteen `f32` lanes and sixteen-lane masks, for code that runs one computation on
//! many values at once (the path tracer's lanes). Every operation is the IEEE operation
//! of `f32` on each lane, so a lane's result equals the scalar code's bit for bit; each
//! is a fixed loop over the lanes that the compiler makes into one vector instruction
//! (one AVX-512 instruction, or several narrower ones, where the caller is compiled for
//! them).

// Indexed loops over the lanes are the form the vectoriser turns into one instruction.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, BitAnd, BitOr, Div, Index, IndexMut, Mul, Neg, Not, Sub};

/// Lanes per vector.
pub const LANES: usize = 16;

/// Sixteen `f32`s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(64))]
pub struct F32x16(pub [f32; LANES]);

/// Sixteen booleans.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Mask16(pub [bool; LANES]);

impl F32x16 {
    pub const ZERO: F32x16 = F32x16([0.0; LANES]);

    #[inline(always)]
    pub fn splat(v: f32) -> F32x16 {
        F32x16([v; LANES])
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> F32x16 {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i]);
        }
        F32x16(r)
    }

    #[inline(always)]
    fn zip(self, b: F32x16, f: impl Fn(f32, f32) -> f32) -> F32x16 {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i], b.0[i]);
        }
        F32x16(r)
    }

    #[inline(always)]
    fn test(self, b: F32x16, f: impl Fn(f32, f32) -> bool) -> Mask16 {
        let mut r = [false; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i], b.0[i]);
        }
        Mask16(r)
    }

    #[inline(always)]
    pub fn abs(self) -> F32x16 {
        self.map(f32::abs)
    }

    #[inline(always)]
    pub fn sqrt(self) -> F32x16 {
        self.map(f32::sqrt)
    }

    /// `f32::max` per lane.
    #[inline(always)]
    pub fn max(self, b: F32x16) -> F32x16 {
        self.zip(b, f32::max)
    }

    /// `f32::min` per lane.
    #[inline(always)]
    pub fn min(self, b: F32x16) -> F32x16 {
        self.zip(b, f32::min)
    }

    /// `f32::copysign` per lane: `self`'s magnitude with `sign`'s sign.
    #[inline(always)]
    pub fn copysign(self, sign: F32x16) -> F32x16 {
        self.zip(sign, f32::copysign)
    }

    #[inline(always)]
    pub fn lt(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x < y)
    }

    #[inline(always)]
    pub fn le(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x <= y)
    }

    #[inline(always)]
    pub fn gt(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x > y)
    }

    #[inline(always)]
    pub fn ge(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x >= y)
    }

    /// `==` per lane (false where either is NaN).
    #[inline(always)]
    pub fn eq(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x == y)
    }

    /// `!=` per lane (true where either is NaN).
    #[inline(always)]
    pub fn ne(self, b: F32x16) -> Mask16 {
        self.test(b, |x, y| x != y)
    }

    #[inline(always)]
    pub fn is_finite(self) -> Mask16 {
        self.test(self, |x, _| x.is_finite())
    }

    #[inline(always)]
    pub fn is_infinite(self) -> Mask16 {
        self.test(self, |x, _| x.is_infinite())
    }

    /// `f(self, b)` per lane, for a lane operation this type does not name (it must be
    /// simple enough to vectorise).
    #[inline(always)]
    pub fn lanewise(self, b: F32x16, f: impl Fn(f32, f32) -> f32) -> F32x16 {
        self.zip(b, f)
    }
}

impl Mask16 {
    /// `a` where the mask is set, else `b`.
    #[inline(always)]
    pub fn select(self, a: F32x16, b: F32x16) -> F32x16 {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] { a.0[i] } else { b.0[i] };
        }
        F32x16(r)
    }
}

macro_rules! binary {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for F32x16 {
            type Output = F32x16;
            #[inline(always)]
            fn $f(self, b: F32x16) -> F32x16 {
                self.zip(b, |x, y| x $op y)
            }
        }
        impl $tr<f32> for F32x16 {
            type Output = F32x16;
            #[inline(always)]
            fn $f(self, b: f32) -> F32x16 {
                self.map(|x| x $op b)
            }
        }
        impl $tr<F32x16> for f32 {
            type Output = F32x16;
            #[inline(always)]
            fn $f(self, b: F32x16) -> F32x16 {
                b.map(|y| self $op y)
            }
        }
    };
}
binary!(Add, add, +);
binary!(Sub, sub, -);
binary!(Mul, mul, *);
binary!(Div, div, /);

impl Neg for F32x16 {
    type Output = F32x16;
    #[inline(always)]
    fn neg(self) -> F32x16 {
        self.map(|x| -x)
    }
}

impl Index<usize> for F32x16 {
    type Output = f32;
    #[inline(always)]
    fn index(&self, i: usize) -> &f32 {
        &self.0[i]
    }
}

impl IndexMut<usize> for F32x16 {
    #[inline(always)]
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        &mut self.0[i]
    }
}

macro_rules! logic {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Mask16 {
            type Output = Mask16;
            #[inline(always)]
            fn $f(self, b: Mask16) -> Mask16 {
                let mut r = [false; LANES];
                for i in 0..LANES {
                    r[i] = self.0[i] $op b.0[i];
                }
                Mask16(r)
            }
        }
    };
}
logic!(BitAnd, bitand, &);
logic!(BitOr, bitor, |);

impl Not for Mask16 {
    type Output = Mask16;
    #[inline(always)]
    fn not(self) -> Mask16 {
        let mut r = [false; LANES];
        for i in 0..LANES {
            r[i] = !self.0[i];
        }
        Mask16(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_equal_scalar_operations() {
        let a = F32x16(std::array::from_fn(|i| i as f32 * 0.37 - 2.0));
        let b = F32x16(std::array::from_fn(|i| 1.5 - i as f32 * 0.21));
        let mut nan = b;
        nan[3] = f32::NAN;
        for i in 0..LANES {
            assert_eq!((a + b)[i], a[i] + b[i]);
            assert_eq!((a - b)[i], a[i] - b[i]);
            assert_eq!((a * b)[i], a[i] * b[i]);
            assert_eq!((a / b)[i].to_bits(), (a[i] / b[i]).to_bits());
            assert_eq!((2.0 * a)[i], 2.0 * a[i]);
            assert_eq!(a.abs().sqrt()[i], a[i].abs().sqrt());
            assert_eq!(a.max(nan)[i], a[i].max(nan[i]));
            assert_eq!(a.copysign(b)[i], a[i].copysign(b[i]));
            assert_eq!(a.lt(nan).0[i], a[i] < nan[i]);
            assert_eq!(a.ne(nan).0[i], a[i] != nan[i]);
            assert_eq!(nan.is_finite().0[i], nan[i].is_finite());
            let m = a.gt(b) | nan.eq(nan);
            assert_eq!(m.select(a, b)[i], if m.0[i] { a[i] } else { b[i] });
        }
    }
}
