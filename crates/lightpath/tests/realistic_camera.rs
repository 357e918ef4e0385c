//! The realistic camera (a lens system from a prescription file) in whole renders: the
//! lightwave and Mitsuba readers, the renderer's use of its weights, and its image
//! against a pinhole camera of the same field of view.

use lightpath::camera::{Camera, LAMBDA_D};
use lightpath::film::Image;
use lightpath::io::{load_scene_str, LoadOptions};
use std::path::{Path, PathBuf};
mod common;
use common::render_loaded as render;

fn lens(name: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/lenses")
        .join(name);
    p.to_string_lossy().into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("lightpath-realistic-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn load(xml: &str) -> lightpath::io::LoadedScene {
    load_scene_str(xml, Path::new("test.xml"), &LoadOptions::default()).unwrap()
}

/// A smooth colour pattern, written as a linear EXR texture.
fn pattern(dir: &Path) -> PathBuf {
    let n = 256;
    let mut img = Image::new(n, n);
    for y in 0..n {
        for x in 0..n {
            let (u, v) = (x as f32 / n as f32, y as f32 / n as f32);
            let tau = std::f32::consts::TAU;
            img.pixels[(y * n + x) as usize] = glam::Vec3::new(
                0.6 + 0.35 * (tau * 6.0 * u).sin() * (tau * 2.0 * v).cos(),
                0.5 + 0.3 * (tau * 4.0 * v).sin() + 0.15 * u,
                0.4 + 0.3 * (tau * 5.0 * (u + v)).cos(),
            );
        }
    }
    let path = dir.join("pattern.exr");
    lightpath::io::image::write_image(&path, &img).unwrap();
    path
}

/// A textured emitter far away (2 km, 2 km wide) facing the camera, seen by `camera`.
fn far_wall(camera: &str, texture: &Path) -> String {
    format!(
        r#"<integrator type="direct"><scene>
            {camera}
            <instance><shape type="rectangle"/>
                <emission type="lambertian"><texture name="emission" type="image" filename="{}" linear="true"/></emission>
                <bsdf type="diffuse"><texture name="albedo" type="constant" value="0"/></bsdf>
                <transform><rotate axis="1,0,0" angle="180"/><scale value="1000"/><translate z="2000"/></transform>
            </instance>
        </scene><sampler type="sobol" count="256"/></integrator>"#,
        texture.display()
    )
}

/// relMSE over the pixels within `fraction` of the half-diagonal of the centre.
fn central_relmse(a: &Image, b: &Image, fraction: f32) -> f64 {
    let (w, h) = (a.width as f32, a.height as f32);
    let r_max = fraction * 0.5 * w.hypot(h);
    let (mut sum, mut n) = (0.0f64, 0usize);
    for y in 0..a.height {
        for x in 0..a.width {
            let dx = x as f32 + 0.5 - 0.5 * w;
            let dy = y as f32 + 0.5 - 0.5 * h;
            if dx.hypot(dy) > r_max {
                continue;
            }
            let (p, q) = (a.get(x, y), b.get(x, y));
            for c in 0..3 {
                sum += ((p[c] - q[c]) as f64).powi(2) / ((q[c] as f64).powi(2) + 1e-2);
            }
            n += 3;
        }
    }
    sum / n as f64
}

/// Stopped down to f/14 and focused at infinity, the symmetric double doublet images a
/// far wall as a pinhole camera with the field of view 2·atan(film half-width / f) does:
/// the same magnification, upright, exposed alike at the centre. The metric is relMSE
/// (per channel, (a-b)²/(b²+0.01)) over the central 40% of the half-diagonal, where the
/// lens' falloff stays under 3%; a 3% larger field of view or a mirrored image fails.
#[test]
fn a_stopped_down_lens_images_like_a_pinhole() {
    let dir = scratch("pinhole");
    let texture = pattern(&dir);
    let size = r#"<integer name="width" value="80"/><integer name="height" value="60"/>"#;
    let realistic = load(&far_wall(
        &format!(
            r#"<camera type="realistic">{size}<string name="lensFile" value="{}"/>
                <float name="apertureDiameter" value="4"/><float name="focusDistance" value="1e6"/>
                <boolean name="dispersion" value="false"/></camera>"#,
            lens("double-doublet.50mm.dat")
        ),
        &texture,
    ));
    let Some(Camera::Realistic(cam)) = realistic.scene.camera.as_ref() else {
        panic!("not a realistic camera");
    };
    let f = cam.effective_focal_length(LAMBDA_D).unwrap();
    // 35 mm diagonal over 80x60 pixels: 28 mm wide.
    let fov = |scale: f64| 2.0 * (14.0 * scale / f).atan().to_degrees();
    let pinhole = |fov: f64, mirror: bool| {
        let flip = if mirror {
            r#"<transform><scale x="-1"/></transform>"#
        } else {
            ""
        };
        render(&load(&far_wall(
            &format!(
                r#"<camera type="perspective">{size}<float name="fov" value="{fov}"/>{flip}</camera>"#
            ),
            &texture,
        )))
    };
    let through_lens = render(&realistic);
    let same = central_relmse(&through_lens, &pinhole(fov(1.0), false), 0.4);
    let wider = central_relmse(&through_lens, &pinhole(fov(1.03), false), 0.4);
    let mirrored = central_relmse(&through_lens, &pinhole(fov(1.0), true), 0.4);
    assert!(same < 1e-3, "relMSE {same}");
    assert!(wider > 3.0 * same, "a 3% wider view: {wider} vs {same}");
    assert!(mirrored > 10.0 * same, "mirrored: {mirrored} vs {same}");
}

/// A small bright light off the axis, seen through the double doublet wide open: with
/// `flare`, ghosts put light where the direct image has none (far from the light's
/// image), a small fraction of it; without, those pixels stay black.
#[test]
fn flare_puts_ghosts_away_from_the_light() {
    let scene = |flare: bool| {
        format!(
            r#"<integrator type="direct"><scene>
                <camera type="realistic"><integer name="width" value="240"/><integer name="height" value="160"/>
                    <string name="lensFile" value="{}"/><float name="focusDistance" value="5"/>
                    <boolean name="flare" value="{flare}"/><integer name="blades" value="6"/></camera>
                <instance><shape type="sphere"/>
                    <emission type="lambertian"><texture name="emission" type="constant" value="100"/></emission>
                    <bsdf type="diffuse"><texture name="albedo" type="constant" value="0"/></bsdf>
                    <transform><scale value="0.15"/><translate x="0.9" y="-0.5" z="5"/></transform>
                </instance>
            </scene><sampler type="independent" count="256"/></integrator>"#,
            lens("double-doublet.50mm.dat")
        )
    };
    let plain = render(&load(&scene(false)));
    let flared = render(&load(&scene(true)));
    // The light's image: the brightest pixel without flare.
    let (mut bx, mut by, mut best) = (0, 0, 0.0);
    for y in 0..plain.height {
        for x in 0..plain.width {
            if plain.get(x, y).y > best {
                (bx, by, best) = (x, y, plain.get(x, y).y);
            }
        }
    }
    let far = |x: u32, y: u32| {
        (x as i32 - bx as i32)
            .abs()
            .max((y as i32 - by as i32).abs())
            > 30
    };
    let (mut total, mut ghosts_plain, mut ghosts_flared) = (0.0f64, 0.0f64, 0.0f64);
    for y in 0..plain.height {
        for x in 0..plain.width {
            total += plain.get(x, y).y as f64;
            if far(x, y) {
                ghosts_plain += plain.get(x, y).y as f64;
                ghosts_flared += flared.get(x, y).y as f64;
            }
        }
    }
    assert!(
        best > 0.0 && bx > plain.width / 2 && by < plain.height / 2,
        "the light's image at ({bx}, {by})"
    );
    assert_eq!(ghosts_plain, 0.0);
    let fraction = ghosts_flared / total;
    assert!(fraction > 1e-4 && fraction < 0.05, "ghost light {fraction}");
}

#[test]
fn scene_errors_name_the_place() {
    let bad = scratch("errors").join("bad.dat");
    std::fs::write(&bad, "# a lens\n50 5 1.5168 20\n-50 47 one 20\n").unwrap();
    let camera = |props: &str| {
        format!(
            r#"<integrator type="direct"><scene>
<camera type="realistic">{props}</camera>
</scene><sampler type="independent" count="1"/></integrator>"#
        )
    };
    let err = |xml: &str| {
        load_scene_str(xml, Path::new("scene.xml"), &LoadOptions::default())
            .err()
            .unwrap()
            .to_string()
    };
    let e = err(&camera(""));
    assert!(
        e.contains("scene.xml:2") && e.contains("needs a `lensFile`"),
        "{e}"
    );
    let e = err(&camera(&format!(
        r#"<string name="lensFile" value="{}"/>"#,
        bad.display()
    )));
    assert!(
        e.contains("bad.dat: line 3: `one` is not a finite number"),
        "{e}"
    );
    let e = err(&camera(&format!(
        r#"<string name="lensFile" value="{}"/><float name="apertureDiameter" value="30"/>"#,
        lens("achromat.50mm.dat")
    )));
    assert!(
        e.contains("scene.xml:2") && e.contains("stop of 16 mm"),
        "{e}"
    );
    let e = err(&camera(&format!(
        r#"<string name="lensFile" value="{}"/><string name="flareSampling" value="film"/>"#,
        lens("achromat.50mm.dat")
    )));
    assert!(
        e.contains("scene.xml:2") && e.contains("`flareSampling` must be `light` or `camera`"),
        "{e}"
    );
}

#[test]
fn mitsuba_scenes_take_a_realistic_sensor() {
    let xml = format!(
        r#"<scene version="3.0.0">
            <sensor type="realistic">
                <string name="lens_file" value="{}"/>
                <float name="aperture_diameter" value="8"/>
                <float name="focus_distance" value="2"/>
                <boolean name="flare" value="true"/>
                <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
            </sensor>
            <shape type="sphere"><bsdf type="diffuse"/></shape>
        </scene>"#,
        lens("achromat.50mm.dat")
    );
    let loaded = load(&xml);
    let Some(Camera::Realistic(cam)) = loaded.scene.camera.as_ref() else {
        panic!("not a realistic camera");
    };
    assert!(cam.uses_path_sample());
    assert_eq!(cam.resolution, glam::UVec2::new(32, 24));
    // Ghosts from the lights by default; from camera rays with `flare_sampling`.
    assert!(cam.traces_ghosts_from_lights());
    let xml = xml.replace(
        r#"<boolean name="flare" value="true"/>"#,
        r#"<boolean name="flare" value="true"/><string name="flare_sampling" value="camera"/>"#,
    );
    let loaded = load(&xml);
    let Some(Camera::Realistic(cam)) = loaded.scene.camera.as_ref() else {
        panic!("not a realistic camera");
    };
    assert!(!cam.traces_ghosts_from_lights());
}

/// Ghosts traced from the light (the default) against ghosts found by camera rays:
/// the same image, in the ghosts' light away from the light's own image (8×8-pixel
/// blocks and the sum over them). A bright sphere off the axis and an uncoated lens,
/// so that the camera rays' ghosts converge at a sample count a test can afford; the
/// light-traced ghosts are the nearly noise-free ones.
#[test]
fn ghosts_from_the_lights_match_ghosts_from_the_camera() {
    let scene = |sampling: &str, spp: u32| {
        format!(
            r#"<integrator type="direct"><scene>
                <camera type="realistic"><integer name="width" value="48"/><integer name="height" value="32"/>
                    <string name="lensFile" value="{}"/><float name="focusDistance" value="4"/>
                    <boolean name="flare" value="true"/><boolean name="coated" value="false"/>
                    <boolean name="dispersion" value="false"/>
                    <string name="flareSampling" value="{sampling}"/></camera>
                <instance><shape type="sphere"/>
                    <emission type="lambertian"><texture name="emission" type="constant" value="40"/></emission>
                    <bsdf type="diffuse"><texture name="albedo" type="constant" value="0"/></bsdf>
                    <transform><scale value="0.25"/><translate x="0.8" y="-0.45" z="4"/></transform>
                </instance>
            </scene><sampler type="independent" count="{spp}"/></integrator>"#,
            lens("double-doublet.50mm.dat")
        )
    };
    let camera = render(&load(&scene("camera", 16384)));
    let light = render(&load(&scene("light", 256)));
    // The light's own image: pixels brighter than 1 in either render, grown by 3.
    let (w, h) = (camera.width, camera.height);
    let bright = |x: u32, y: u32| {
        let mut b = false;
        for dy in -3i32..=3 {
            for dx in -3i32..=3 {
                let (xx, yy) = (x as i32 + dx, y as i32 + dy);
                if xx >= 0 && yy >= 0 && (xx as u32) < w && (yy as u32) < h {
                    b |= camera.get(xx as u32, yy as u32).y > 1.0
                        || light.get(xx as u32, yy as u32).y > 1.0;
                }
            }
        }
        b
    };
    let mut blocks = Vec::new();
    let (mut sum_c, mut sum_l) = (0.0f64, 0.0f64);
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let (mut c, mut l, mut n) = (0.0f64, 0.0f64, 0);
            for y in by * 8..by * 8 + 8 {
                for x in bx * 8..bx * 8 + 8 {
                    if !bright(x, y) {
                        let (a, b) = (camera.get(x, y), light.get(x, y));
                        c += (a.x + a.y + a.z) as f64;
                        l += (b.x + b.y + b.z) as f64;
                        n += 1;
                    }
                }
            }
            if n > 32 {
                blocks.push((bx, by, c, l));
                sum_c += c;
                sum_l += l;
            }
        }
    }
    eprintln!("ghost light: camera {sum_c:.4}, light {sum_l:.4}");
    assert!(
        sum_c > 0.0 && blocks.len() > 12,
        "{sum_c} over {} blocks",
        blocks.len()
    );
    // Camera rays leave about 3% noise per block at this count.
    for (bx, by, c, l) in &blocks {
        assert!(
            (l / c - 1.0).abs() < 0.12,
            "block ({bx}, {by}): light {l} against camera {c}"
        );
    }
    assert!(
        (sum_l / sum_c - 1.0).abs() < 0.025,
        "ghost light {sum_l} against {sum_c}"
    );
}
