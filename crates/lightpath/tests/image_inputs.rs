//! Every image format lightpath reads (PNG, JPEG, Radiance HDR, OpenEXR) loads as a
//! surface texture and as an environment map, in both scene dialects.

use lightpath::film::Image;
use lightpath::io::{load_scene_str, LoadOptions};
use lightpath::light::Light;
use lightpath::math::{Vec2, Vec3};
use std::path::{Path, PathBuf};

/// A flat colour in `dir/flat.<ext>`; 8-bit formats get sRGB code 128.
fn write_flat(dir: &Path, ext: &str) -> (PathBuf, Vec3) {
    let path = dir.join(format!("flat.{ext}"));
    match ext {
        "jpg" => {
            image::RgbImage::from_pixel(8, 4, image::Rgb([128, 128, 128]))
                .save(&path)
                .unwrap();
            let v = lightpath::io::image::srgb_to_linear(128.0 / 255.0);
            (path, Vec3::splat(v))
        }
        "png" => {
            let v = lightpath::io::image::srgb_to_linear(128.0 / 255.0);
            let image = Image {
                width: 8,
                height: 4,
                pixels: vec![Vec3::splat(v); 32],
            };
            lightpath::io::image::write_image(&path, &image).unwrap();
            (path, Vec3::splat(v))
        }
        _ => {
            let c = Vec3::new(0.25, 0.5, 2.0);
            let image = Image {
                width: 8,
                height: 4,
                pixels: vec![c; 32],
            };
            lightpath::io::image::write_image(&path, &image).unwrap();
            (path, c)
        }
    }
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= 0.02 * b.max_element()
}

#[test]
fn png_jpeg_hdr_exr_load_as_textures_and_environments() {
    let dir = std::env::temp_dir().join(format!("lightpath-image-inputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for ext in ["png", "jpg", "hdr", "exr"] {
        let (path, colour) = write_flat(&dir, ext);
        let file = path.file_name().unwrap().to_str().unwrap();

        // Mitsuba 3: a bitmap texture and an envmap.
        let xml = format!(
            r#"<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
  <emitter type="envmap"><string name="filename" value="{file}"/></emitter>
  <shape type="sphere">
    <bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{file}"/></texture></bsdf>
  </shape>
</scene>"#
        );
        let loaded = load_scene_str(&xml, &dir.join("scene.xml"), &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{ext}: {e}"));
        let albedo = loaded.scene.instances[0]
            .material
            .as_ref()
            .unwrap()
            .albedo(Vec2::new(0.3, 0.6));
        assert!(close(albedo, colour), "{ext}: texture {albedo} vs {colour}");
        let Some(Light::Environment(env)) = loaded.scene.lights.first() else {
            panic!("{ext}: no environment");
        };
        let sky = env.eval(Vec3::new(0.3, 0.5, 0.8).normalize());
        assert!(close(sky, colour), "{ext}: environment {sky} vs {colour}");

        // Lightwave: an image texture and an envmap light.
        let xml = format!(
            r#"<integrator type="direct"><scene>
  <camera type="perspective"><integer name="width" value="4"/><integer name="height" value="4"/></camera>
  <light type="envmap"><texture type="image" filename="{file}"/></light>
  <instance><shape type="sphere"/>
    <bsdf type="diffuse"><texture name="albedo" type="image" filename="{file}"/></bsdf>
  </instance>
</scene><sampler type="independent" count="1"/></integrator>"#
        );
        let loaded = load_scene_str(&xml, &dir.join("scene.xml"), &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{ext} (lightwave): {e}"));
        let albedo = loaded.scene.instances[0]
            .material
            .as_ref()
            .unwrap()
            .albedo(Vec2::new(0.3, 0.6));
        // The lightwave dialect decodes 8-bit textures with γ = 2.2, as the course does.
        assert!(
            (albedo - colour).abs().max_element() <= 0.03 * colour.max_element(),
            "{ext} (lightwave): texture {albedo} vs {colour}"
        );
        let Some(Light::Environment(env)) = loaded.scene.lights.first() else {
            panic!("{ext} (lightwave): no environment");
        };
        let sky = env.eval(Vec3::new(-0.4, 0.1, 0.9).normalize());
        assert!(
            (sky - colour).abs().max_element() <= 0.03 * colour.max_element(),
            "{ext} (lightwave): environment {sky} vs {colour}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
