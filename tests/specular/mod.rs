//! Specular chains under `ltc` and `ratio` (issue 19): scenes with a mirror and glass, and
//! their comparison with `directlighting`, which follows perfectly specular lobes as pbrt-v3
//! does. Shared by `tests/ltc.rs` and `tests/ratio.rs`.
#![allow(dead_code)]

use super::common::*;
use std::path::PathBuf;

/// A scene with specular surfaces: its text, where its relative paths start, and the
/// `Material` lines of its specular objects (replaced by a black matte to find their pixels).
pub struct SpecularScene {
    pub name: &'static str,
    pub text: String,
    pub dir: PathBuf,
    pub specular_materials: Vec<&'static str>,
}

/// The public dragon scenes: a mirror floor under a matte dragon, a glass dragon on a matte
/// floor, both lit by an image-mapped infinite light only.
pub fn dragon(name: &'static str) -> SpecularScene {
    let path = scene(&format!("public/hackmad-pbrt-v3-rs/scenes/materials/{name}.pbrt"));
    let text = std::fs::read_to_string(&path).unwrap();
    let material = match name {
        "mirror" => "Material \"mirror\" \"color Kr\" [.9 .6 .6]",
        "glass" => "Material \"glass\"",
        _ => panic!("no such dragon scene: {name}"),
    };
    SpecularScene { name, text, dir: path.parent().unwrap().to_path_buf(), specular_materials: vec![material] }
}

/// A quad light over a matte floor with a matte ball casting a shadow, a mirror standing
/// behind them (it shows the floor, the shadow and the light's underside) and a glass ball (a
/// lens onto the floor): area lights reached through specular chains, with shadows, where
/// `ltc`'s analytic shading and `ratio`'s estimator do the work.
pub fn area_lit() -> SpecularScene {
    let text = r#"
LookAt 0 2.2 -5  0 0.7 1  0 1 0
Camera "perspective" "float fov" [ 50 ]
Film "image" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ] "string filename" [ "out.exr" ]
Sampler "halton" "integer pixelsamples" [ 16 ]
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 6 6 6 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -1 3 -1  1 3 -1  1 3 1  -1 3 1 ]
      "normal N" [ 0 -1 0 0 -1 0 0 -1 0 0 -1 0 ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.6 0.5 0.4 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -10 0 -10  -10 0 10  10 0 10  10 0 -10 ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.3 0.5 0.3 ]
  Translate 0.9 0.7 -0.6
  Shape "sphere" "float radius" [ 0.35 ]
AttributeEnd
AttributeBegin
  Material "mirror" "rgb Kr" [ 0.9 0.9 0.9 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -2.5 0 2.2  2.5 0 2.2  2.5 2.4 2.6  -2.5 2.4 2.6 ]
AttributeEnd
AttributeBegin
  Material "glass"
  Translate -1.1 0.55 -0.2
  Shape "sphere" "float radius" [ 0.55 ]
AttributeEnd
"#;
    SpecularScene {
        name: "area-lit",
        text: text.to_string(),
        dir: root(),
        specular_materials: vec!["Material \"mirror\" \"rgb Kr\" [ 0.9 0.9 0.9 ]", "Material \"glass\""],
    }
}

impl SpecularScene {
    /// Renders the scene (`text` replacing the scene's) at `res`×`res`.
    fn render_with(&self, text: &str, integrator: &str, params: &[&str], spp: u32, res: u32) -> Render {
        let parsed = penumbra_parser::parse_str(text, self.name, Some(&self.dir)).unwrap_or_else(|e| panic!("{e}"));
        let o = Opts {
            integrator: Some(integrator),
            params,
            spp: Some(spp),
            resolution: Some((res, res)),
            ..Default::default()
        };
        render_desc(&parsed.scene, &o)
    }

    pub fn render(&self, integrator: &str, params: &[&str], spp: u32, res: u32) -> Render {
        self.render_with(&self.text, integrator, params, spp, res)
    }

    /// The pixels wholly covered by the specular objects and lit: under `directlighting`, black
    /// (every channel exactly 0) once their materials are a black matte, and not once they are
    /// a white one.
    pub fn specular_pixels(&self, res: u32) -> Vec<usize> {
        let matte = |kd: &str| {
            let mut text = self.text.clone();
            for m in &self.specular_materials {
                assert!(text.contains(m), "{}: no {m}", self.name);
                text = text.replace(m, &format!("Material \"matte\" \"rgb Kd\" [ {kd} {kd} {kd} ]"));
            }
            self.render_with(&text, "directlighting", &[], 4, res)
        };
        let (black, white) = (matte("0"), matte("1"));
        let is_black = |r: &Render, p: usize| r.image.data[p * 3..p * 3 + 3].iter().all(|v| *v == 0.0);
        (0..(res * res) as usize).filter(|&p| is_black(&black, p) && !is_black(&white, p)).collect()
    }
}

/// Mean of the given pixels' values.
pub fn mean_over(img: &Render, pixels: &[usize]) -> f64 {
    let sum: f64 = pixels.iter().flat_map(|&p| img.image.data[p * 3..p * 3 + 3].iter()).map(|v| *v as f64).sum();
    sum / (3 * pixels.len()).max(1) as f64
}

/// `integrator` (with `params`, `spp` camera samples) against `directlighting` at `dl_spp` on
/// `scene`: the image means and the specular pixels' means within `tol` (relative), the
/// specular pixels at least 5 % of the image, none of them black where `directlighting`'s is
/// not. Prints the figures.
pub fn assert_matches_directlighting(
    scene: &SpecularScene,
    integrator: &str,
    params: &[&str],
    (spp, dl_spp, res): (u32, u32, u32),
    tol: f64,
) {
    let spec = scene.specular_pixels(res);
    let n = (res * res) as usize;
    assert!(spec.len() * 20 >= n, "{}: only {} specular pixels of {n}", scene.name, spec.len());
    let dl = scene.render("directlighting", &[], dl_spp, res);
    let ours = scene.render(integrator, params, spp, res);
    assert!(ours.image.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{}: bad values", scene.name);
    let (m, m_dl) = (mean(&ours.image), mean(&dl.image));
    let (s, s_dl) = (mean_over(&ours, &spec), mean_over(&dl, &spec));
    let is_black = |r: &Render, p: usize| r.image.data[p * 3..p * 3 + 3].iter().all(|v| *v == 0.0);
    let black = spec.iter().filter(|&&p| is_black(&ours, p) && !is_black(&dl, p)).count();
    eprintln!(
        "{} {integrator} {params:?} ({spp} spp) vs directlighting ({dl_spp} spp), {res}x{res}: image mean {m:.5} vs \
         {m_dl:.5} ({:+.3}%); {} specular pixels: mean {s:.5} vs {s_dl:.5} ({:+.3}%), {black} black",
        scene.name,
        (m / m_dl - 1.0) * 100.0,
        spec.len(),
        (s / s_dl - 1.0) * 100.0
    );
    assert_eq!(black, 0, "{}: {black} black specular pixels", scene.name);
    assert!((m / m_dl - 1.0).abs() < tol, "{}: image mean {m} vs directlighting's {m_dl}", scene.name);
    assert!((s / s_dl - 1.0).abs() < tol, "{}: specular pixels' mean {s} vs directlighting's {s_dl}", scene.name);
}
