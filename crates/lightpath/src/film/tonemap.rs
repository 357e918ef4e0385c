//! Tone mapping for display: scene-linear radiance → display-linear values in [0, 1],
//! which the 8-bit writers then sRGB-encode. Linear outputs (EXR) are never tone mapped.
//!
//! | name       | curve                                                                 |
//! |------------|-----------------------------------------------------------------------|
//! | `clamp`    | none: values are clipped to [0, 1] (the default; what PNG output always did) |
//! | `reinhard` | `x / (1 + x)` per channel                                             |
//! | `aces`     | Krzysztof Narkowicz's rational fit of the ACES reference rendering and output transforms, per channel, after his suggested 0.6 pre-scale |
//! | `agx`      | Troy Sobotka's AgX view as approximated by Benjamin Wrensch: an "inset" matrix, a log2 encoding over [-12.47, +4.03] stops around 0.18, a sixth-degree polynomial fit of AgX's sigmoid, the inverse matrix, and a 2.2 power back to linear |
//!
//! Every operator maps 0 to 0, never decreases along a grey ramp, and maps anything
//! (negative, NaN, infinite) into [0, 1]. Exposure multiplies by 2^EV before the curve.

use super::Image;
use glam::{Mat3, Vec3};

/// A tone-mapping operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Clip to [0, 1].
    #[default]
    Clamp,
    /// `x / (1 + x)`.
    Reinhard,
    /// Narkowicz's ACES fit.
    Aces,
    /// Wrensch's AgX approximation.
    Agx,
}

/// Inputs are clipped to [0, LARGEST] first (NaN → 0) so the curves never see NaN or
/// infinity; every curve is at 1 long before this.
const LARGEST: f32 = 1e6;

impl Tonemap {
    /// Names accepted by [`Tonemap::from_name`], in documentation order.
    pub const NAMES: &'static [&'static str] = &["clamp", "reinhard", "aces", "agx"];

    pub fn from_name(name: &str) -> Option<Tonemap> {
        match name {
            "clamp" => Some(Tonemap::Clamp),
            "reinhard" => Some(Tonemap::Reinhard),
            "aces" => Some(Tonemap::Aces),
            "agx" => Some(Tonemap::Agx),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Tonemap::Clamp => "clamp",
            Tonemap::Reinhard => "reinhard",
            Tonemap::Aces => "aces",
            Tonemap::Agx => "agx",
        }
    }

    /// Maps a scene-linear colour (already exposed) to display-linear [0, 1].
    pub fn map(self, c: Vec3) -> Vec3 {
        let c = Vec3::from_array(c.to_array().map(|v| {
            if v.is_nan() {
                0.0
            } else {
                v.clamp(0.0, LARGEST)
            }
        }));
        let out = match self {
            Tonemap::Clamp => c,
            Tonemap::Reinhard => c / (Vec3::ONE + c),
            Tonemap::Aces => c.map(aces_narkowicz),
            Tonemap::Agx => agx(c),
        };
        out.clamp(Vec3::ZERO, Vec3::ONE)
    }

    /// The tone-mapped copy of an image, exposure `ev` stops: display-linear, ready for
    /// sRGB encoding.
    pub fn apply(self, image: &Image, ev: f32) -> Image {
        let scale = exposure_scale(ev);
        Image {
            width: image.width,
            height: image.height,
            pixels: image.pixels.iter().map(|&p| self.map(p * scale)).collect(),
        }
    }
}

/// The factor of an exposure of `ev` stops: 2^ev.
pub fn exposure_scale(ev: f32) -> f32 {
    ev.exp2()
}

/// Narkowicz (2016), "ACES Filmic Tone Mapping Curve": the rational function
/// x(ax + b) / (x(cx + d) + e), whose derivative's numerator
/// (ad - bc)x² + 2aex + be is positive for x ≥ 0, so it increases from 0 towards
/// a/c ≈ 1.03 and is clipped at 1. The 0.6 pre-scale is his, matching the ACES
/// reference's overall exposure.
fn aces_narkowicz(x: f32) -> f32 {
    const A: f32 = 2.51;
    const B: f32 = 0.03;
    const C: f32 = 2.43;
    const D: f32 = 0.59;
    const E: f32 = 0.14;
    let x = x * 0.6;
    (x * (A * x + B)) / (x * (C * x + D) + E)
}

/// AgX's log2 range around middle grey, in stops.
const AGX_MIN_EV: f32 = -12.47393;
const AGX_MAX_EV: f32 = 4.026069;

/// AgX's "inset": pulls colours towards the achromatic axis so that bright saturated
/// colours desaturate as they approach white. Columns of the matrix.
fn agx_inset() -> Mat3 {
    Mat3::from_cols(
        Vec3::new(0.842_479_06, 0.042_328_24, 0.042_375_655),
        Vec3::new(0.078_433_6, 0.878_468_6, 0.078_433_6),
        Vec3::new(0.079_223_745, 0.079_166_13, 0.879_143),
    )
}

/// The inverse of [`agx_inset`] ("outset"), as published with the approximation.
fn agx_outset() -> Mat3 {
    Mat3::from_cols(
        Vec3::new(1.196_879, -0.052_896_85, -0.052_971_635),
        Vec3::new(-0.098_020_88, 1.151_903_1, -0.098_043_45),
        Vec3::new(-0.099_029_74, -0.098_961_18, 1.151_073_7),
    )
}

/// Wrensch's polynomial fit of AgX's default-contrast sigmoid on [0, 1]; its value at
/// 0 is slightly negative, so the result is clipped to [0, 1].
fn agx_sigmoid(x: f32) -> f32 {
    let x2 = x * x;
    let x4 = x2 * x2;
    let y =
        15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x
            - 0.00232;
    y.clamp(0.0, 1.0)
}

fn agx(c: Vec3) -> Vec3 {
    let inset = agx_inset() * c;
    let encoded = inset.map(|v| {
        // log2(0) = -inf is clipped to the bottom of the range like any deep shadow.
        let ev = v.log2().clamp(AGX_MIN_EV, AGX_MAX_EV);
        agx_sigmoid((ev - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV))
    });
    // The sigmoid's output is display-encoded with a 2.2 power; undo it to get
    // display-linear values (the writer applies the sRGB curve).
    (agx_outset() * encoded).max(Vec3::ZERO).powf(2.2)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [Tonemap; 4] = [
        Tonemap::Clamp,
        Tonemap::Reinhard,
        Tonemap::Aces,
        Tonemap::Agx,
    ];

    #[test]
    fn names_round_trip() {
        for op in ALL {
            assert_eq!(Tonemap::from_name(op.name()), Some(op));
        }
        assert_eq!(Tonemap::NAMES.len(), ALL.len());
        assert_eq!(Tonemap::from_name("agX"), None);
        assert_eq!(Tonemap::default(), Tonemap::Clamp);
    }

    #[test]
    fn zero_maps_to_zero() {
        for op in ALL {
            assert_eq!(op.map(Vec3::ZERO), Vec3::ZERO, "{op:?}");
        }
    }

    /// Along a grey ramp from 0 to 1e4 (geometric steps), every channel of every
    /// operator is non-decreasing, and each covers most of [0, 1].
    #[test]
    fn monotonic_on_grey() {
        for op in ALL {
            let mut prev = Vec3::ZERO;
            let mut x = 1e-6f32;
            while x < 1e4 {
                let y = op.map(Vec3::splat(x));
                assert!(
                    y.cmpge(prev).all(),
                    "{op:?}: {x} -> {y}, below {prev} at the previous step"
                );
                prev = y;
                x *= 1.01;
            }
            assert!(prev.min_element() > 0.95, "{op:?} peaks at {prev}");
        }
        // The curves' own shapes: strictly increasing where they are not clipped.
        for x in [0.05f32, 0.1, 0.5, 0.98] {
            assert!(aces_narkowicz(x * 1.01) > aces_narkowicz(x));
            assert!(agx_sigmoid(x * 1.01) > agx_sigmoid(x), "{x}");
        }
    }

    /// Each channel is non-decreasing in that channel with the others held fixed.
    #[test]
    fn monotonic_per_channel_for_per_channel_curves() {
        for op in [Tonemap::Clamp, Tonemap::Reinhard, Tonemap::Aces] {
            for base in [Vec3::ZERO, Vec3::new(0.3, 2.0, 0.05)] {
                let mut prev = op.map(base);
                for i in 1..2000 {
                    let c = base + Vec3::new(i as f32 * 0.01, 0.0, 0.0);
                    let y = op.map(c);
                    assert!(y.x >= prev.x, "{op:?} {c}");
                    prev = y;
                }
            }
        }
    }

    #[test]
    fn range_is_zero_to_one() {
        let specials = [
            -1.0,
            -0.0,
            1e-30,
            0.18,
            1.0,
            7.5,
            1e3,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for op in ALL {
            for &r in &specials {
                for &g in &specials {
                    for &b in &[0.0, 0.5, f32::NAN, 1e9] {
                        let y = op.map(Vec3::new(r, g, b));
                        assert!(
                            y.is_finite() && y.cmpge(Vec3::ZERO).all() && y.cmple(Vec3::ONE).all(),
                            "{op:?}({r}, {g}, {b}) = {y}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn known_values() {
        // Clamp is the identity on [0, 1].
        assert_eq!(Tonemap::Clamp.map(Vec3::splat(0.25)), Vec3::splat(0.25));
        assert_eq!(Tonemap::Reinhard.map(Vec3::ONE), Vec3::splat(0.5));
        // Narkowicz's curve at 1 (after the 0.6 pre-scale): 0.6(2.51·0.6 + 0.03) /
        // (0.6(2.43·0.6 + 0.59) + 0.14).
        let expected = 0.6 * (2.51 * 0.6 + 0.03) / (0.6 * (2.43 * 0.6 + 0.59) + 0.14);
        assert!((Tonemap::Aces.map(Vec3::ONE).x - expected).abs() < 1e-6);
        // AgX: middle grey lands near the middle of the display range; white is bright.
        let grey = Tonemap::Agx.map(Vec3::splat(0.18));
        assert!((grey.x - grey.z).abs() < 1e-3, "{grey}");
        assert!(grey.x > 0.1 && grey.x < 0.3, "{grey}");
        // The matrices are inverses of each other.
        let m = agx_outset() * agx_inset();
        assert!(m.abs_diff_eq(Mat3::IDENTITY, 1e-4), "{m}");
        // Exposure: +1 EV doubles.
        let mut image = Image::new(1, 1);
        image.set(0, 0, Vec3::splat(0.2));
        assert_eq!(
            Tonemap::Clamp.apply(&image, 1.0).get(0, 0),
            Vec3::splat(0.4)
        );
        assert_eq!(exposure_scale(-2.0), 0.25);
    }
}
