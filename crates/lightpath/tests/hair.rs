//! The hair BSDF on curves, in whole scenes: the fibre runs along the strand, a white
//! fur ball in a uniform environment renders the environment (the furnace), and both
//! scene dialects read the material.

use lightpath::io::{load_scene_str, LoadOptions};
use lightpath::material::Material;
use lightpath::math::Ray;
use std::path::{Path, PathBuf};
mod common;
use common::render_loaded;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightpath-hair-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Strands as Mitsuba's curve files have them: `x y z radius` per point.
fn write_curves(dir: &Path, strands: &[Vec<[f32; 4]>]) -> PathBuf {
    let mut text = String::new();
    for s in strands {
        for p in s {
            text += &format!("{} {} {} {}\n", p[0], p[1], p[2], p[3]);
        }
        text += "\n";
    }
    let path = dir.join("strands.txt");
    std::fs::write(&path, text).unwrap();
    path
}

/// At a hit on a strand along x, the hair BSDF's frame has the fibre (its second axis)
/// along x and the normal across it, in both dialects, on linear and B-spline curves.
#[test]
fn the_fibre_runs_along_the_strand() {
    let dir = scratch("frame");
    let file = write_curves(
        &dir,
        &[vec![
            [-4.0, 0.0, 0.0, 0.2],
            [-2.0, 0.0, 0.0, 0.2],
            [0.0, 0.0, 0.0, 0.2],
            [2.0, 0.0, 0.0, 0.2],
            [4.0, 0.0, 0.0, 0.2],
        ]],
    );
    let mut scenes = Vec::new();
    for (mitsuba_type, basis) in [("linearcurve", "linear"), ("bsplinecurve", "bspline")] {
        scenes.push(format!(
            r#"<scene version="3.0.0">
            <sensor type="perspective"/>
            <shape type="{mitsuba_type}"><string name="filename" value="{}"/>
                <bsdf type="hair"><float name="eumelanin" value="2"/><float name="beta_m" value="0.25"/></bsdf>
            </shape>
        </scene>"#,
            file.display()
        ));
        scenes.push(format!(
            r#"<integrator type="pathtracer"><scene>
            <camera type="perspective"/>
            <instance><shape type="curves" filename="{}" basis="{basis}"/><bsdf type="hair" eumelanin="2" betaM="0.25"/></instance>
        </scene><sampler type="independent"/></integrator>"#,
            file.display()
        ));
    }
    for xml in scenes {
        let loaded = load_scene_str(&xml, Path::new("hair.xml"), &LoadOptions::default()).unwrap();
        let scene = &loaded.scene;
        for (origin, dir) in [
            (
                glam::Vec3::new(0.3, 0.05, 5.0),
                glam::Vec3::new(0.0, 0.0, -1.0),
            ),
            (
                glam::Vec3::new(-1.0, 4.0, 1.0),
                glam::Vec3::new(0.2, -1.0, -0.3),
            ),
        ] {
            let ray = Ray::new(origin, dir.normalize());
            let si = scene.intersect(&ray).expect("the strand is hit");
            let material = scene.material(&si).expect("a material");
            assert!(matches!(material, Material::Hair(_)), "{material:?}");
            let bsdf = material.bsdf(&si, -ray.direction);
            assert!(bsdf.frame.t.x.abs() > 0.999, "fibre axis {}", bsdf.frame.t);
            assert!(bsdf.frame.n.x.abs() < 1e-3, "normal {}", bsdf.frame.n);
        }
    }
}

/// A tangle of white hair (no absorption), as linear and as B-spline curves, under a
/// uniform environment of radiance 1, path traced without a depth limit, renders 1
/// everywhere up to noise: light leaves every fibre as it came, whichever lobe
/// (reflection, transmission through the strand, internal reflection) it takes. Light
/// lost (a strand re-hit from inside, a sample's weight wrong) or created would show in
/// the mean.
#[test]
fn white_hair_in_a_furnace_renders_the_furnace() {
    for basis in ["linear", "bspline"] {
        furnace(basis);
    }
}

fn furnace(basis: &str) {
    let dir = scratch(&format!("furnace-{basis}"));
    let mut strands = Vec::new();
    let mut rng = lightpath::sampling::Pcg32::new(4, 2);
    for _ in 0..150 {
        let mut p =
            glam::Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - glam::Vec3::ONE;
        let mut s = Vec::new();
        for _ in 0..6 {
            s.push([p.x, p.y, p.z, 0.03]);
            p += (glam::Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
                - glam::Vec3::splat(0.5))
                * 0.6;
        }
        strands.push(s);
    }
    let file = write_curves(&dir, &strands);
    let xml = format!(
        r#"<integrator type="pathtracer" depth="-1"><scene>
            <camera type="perspective"><integer name="width" value="24"/><integer name="height" value="24"/>
                <float name="fov" value="40"/><transform><translate z="-5"/></transform></camera>
            <light type="envmap"><texture type="constant" value="1"/></light>
            <instance><shape type="curves" filename="{}" basis="{basis}"/>
                <bsdf type="hair"><rgb name="sigmaA" value="0,0,0"/><float name="betaM" value="0.3"/><float name="betaN" value="0.4"/></bsdf></instance>
        </scene><sampler type="independent" count="64"/></integrator>"#,
        file.display()
    );
    let loaded = load_scene_str(&xml, Path::new("furnace.xml"), &LoadOptions::default()).unwrap();
    let image = render_loaded(&loaded);
    // The pixels whose centre sees hair: many (so the test sees the strands).
    let sees_hair: Vec<bool> = (0..24 * 24)
        .map(|k| {
            let (x, y) = (k % 24, k / 24);
            let d = glam::Vec3::new(
                (x as f32 + 0.5) / 12.0 - 1.0,
                (y as f32 + 0.5) / 12.0 - 1.0,
                1.0 / (20f32.to_radians().tan()),
            );
            let ray = Ray::new(glam::Vec3::new(0.0, 0.0, -5.0), d.normalize());
            loaded.scene.intersect(&ray).is_some()
        })
        .collect();
    let hair: Vec<f64> = image
        .pixels
        .iter()
        .zip(&sees_hair)
        .filter(|(_, s)| **s)
        .flat_map(|(p, _)| [p.x as f64, p.y as f64, p.z as f64])
        .collect();
    assert!(
        hair.len() > 3 * 150,
        "{} of 576 pixels see hair",
        hair.len() / 3
    );
    let mean = hair.iter().sum::<f64>() / hair.len() as f64;
    let worst = hair.iter().map(|v| (v - 1.0).abs()).fold(0.0f64, f64::max);
    eprintln!("furnace, {basis}: mean {mean}, worst pixel off by {worst}");
    // 64 samples leave about 4% noise per pixel; the mean over the hair is within 0.5%.
    assert!(
        (mean - 1.0).abs() < 5e-3,
        "{basis}: mean over the hair {mean}"
    );
    assert!(worst < 0.35, "{basis}: worst pixel off by {worst}");
}
