//! `disney`, `fourier`, `hair` and `subsurface`/`kdsubsurface` end to end: `directlighting` and
//! `path` against the real pbrt-v3's renders of `scenes/materials/` (four objects at parameter
//! extremes each; references in `tests/data/material-references/`, made by
//! `tools/render_material_references.py`): the image mean within 1 %, every value within the
//! noise of both renders, and the means of 8×8 regions (each object covers a few) within 5σ
//! (`path` at half the resolution, see [`check`]).
//! Then what the analytic integrators do with these materials: the estimator's fallback, with
//! a warning naming the material, never a silent matte.

mod common;
use common::*;
use penumbra_core::image::Image;

/// `tests/data/material-references/timings.tsv`: the reference's sample count.
fn reference_spp(name: &str) -> f64 {
    let tsv = std::fs::read_to_string(root().join("tests/data/material-references/timings.tsv")).unwrap();
    let line = tsv.lines().find(|l| l.starts_with(&format!("{name}\t"))).unwrap_or_else(|| panic!("{name} timing"));
    line.split('\t').nth(3).unwrap().parse().unwrap()
}

fn reference(name: &str) -> Image {
    penumbra_core::image::read(root().join(format!("tests/data/material-references/{name}.pfm"))).unwrap()
}

/// The image box-downsampled 2×2 (exact for a box-filtered render: a pixel of the half-size
/// render averages the four pixels it covers).
fn half(img: &Image) -> Image {
    let (w, h) = (img.width as usize / 2, img.height as usize / 2);
    let mut out = img.clone();
    out.width = w as u32;
    out.height = h as u32;
    out.data = vec![0.0; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let at = |dx: usize, dy: usize| img.data[((2 * y + dy) * 2 * w + 2 * x + dx) * 3 + c];
                out.data[(y * w + x) * 3 + c] = 0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1));
            }
        }
    }
    out
}

/// Renders `scenes/materials/SCENE.pbrt` with `integrator` and compares it with reference
/// `NAME` (see the module doc). `directlighting` renders the references' 128×32 at `spp`;
/// `path` renders 64×16 at `spp` against the reference box-downsampled 2×2: its light through
/// the transmissive objects (caustics on the floor, the floor seen through them) is
/// heavy-tailed, and four times the samples per pixel make the per-pixel variances that the
/// comparison trusts see the rare bright paths (two independent 1024-spp renders of
/// disney-transmission at 128×32 differ by up to 11 % in 8×8 regions; at 128 spp a 16×16
/// region ran 5.8 % low with |z| 5.2). Returns the render.
fn check(name: &str, scene_name: &str, integrator: &str, spp: u32) -> Render {
    let desc = penumbra_parser::parse_file(&scene(&format!("materials/{scene_name}.pbrt"))).unwrap().scene;
    let path = integrator == "path";
    let resolution = path.then_some((64, 16));
    let ours =
        render_desc(&desc, &Opts { integrator: Some(integrator), spp: Some(spp), resolution, ..Default::default() });
    let (reference, per_pixel) =
        if path { (half(&reference(name)), 4.0 * reference_spp(name)) } else { (reference(name), reference_spp(name)) };
    let ratio = spp as f64 / per_pixel;
    let label = format!("{name} ({integrator}, {spp} spp)");
    assert_matches_reference(&label, &ours, &reference, ratio, 0.01);
    assert_regions_match(&label, &ours, &reference, ratio, 8);
    ours
}

#[test]
fn disney_reflection_matches_pbrt_v3() {
    check("disney-reflection-dl", "disney-reflection", "directlighting", 256);
    check("disney-reflection-path", "disney-reflection", "path", 512);
}

#[test]
fn disney_transmission_and_thin_match_pbrt_v3() {
    check("disney-transmission-dl", "disney-transmission", "directlighting", 256);
    check("disney-transmission-path", "disney-transmission", "path", 512);
}

#[test]
fn fourier_matches_pbrt_v3() {
    check("fourier-dl", "fourier", "directlighting", 256);
    check("fourier-path", "fourier", "path", 512);
}

/// Hair on cylinders (pbrt-v3's `h = −1 + 2v` along the axis): the fibre's lobes both ways
/// round, with and without absorption, smooth and rough.
#[test]
fn hair_matches_pbrt_v3() {
    check("hair-dl", "hair", "directlighting", 256);
    check("hair-path", "hair", "path", 512);
}

/// `directlighting` renders the interfaces alone (as pbrt-v3's does, with the warning that
/// says so); `path` the BSSRDFs (photon beam diffusion, Burley's profile).
#[test]
fn subsurface_matches_pbrt_v3() {
    let dl = check("subsurface-dl", "subsurface", "directlighting", 256);
    for m in ["subsurface", "kdsubsurface", "disney"] {
        assert!(
            dl.warnings.iter().any(|w| w.contains(&format!("material \"{m}\": its subsurface scattering (BSSRDF)"))),
            "{m}: {:?}",
            dl.warnings
        );
    }
    let path = check("subsurface-path", "subsurface", "path", 1024);
    assert!(!path.warnings.iter().any(|w| w.contains("BSSRDF")), "{:?}", path.warnings);
}

fn render_scene(scene_name: &str, integrator: &str, spp: u32, edit: impl Fn(&mut String)) -> Render {
    let mut text = std::fs::read_to_string(scene(&format!("materials/{scene_name}.pbrt"))).unwrap();
    edit(&mut text);
    let dir = root().join("scenes/materials");
    let parsed = penumbra_parser::parse_str(&text, "<test>", Some(&dir)).unwrap_or_else(|e| panic!("{e}"));
    render_desc(
        &parsed.scene,
        &Opts { integrator: Some(integrator), spp: Some(spp), resolution: None, ..Default::default() },
    )
}

fn warned(r: &Render, what: &str) -> bool {
    r.warnings.iter().any(|w| w.contains(what))
}

/// `ltc` lights a Disney material by directlighting's own estimator under the area light (it
/// has no Lambertian-plus-GGX form), says so naming the material, and so agrees with pbrt-v3's
/// `directlighting` as `directlighting` does (the matte floor's analytic shading and shadows
/// are exact).
#[test]
fn ltc_falls_back_for_disney_and_agrees_with_pbrt_v3() {
    let desc = penumbra_parser::parse_file(&scene("materials/disney-reflection.pbrt")).unwrap().scene;
    let ours =
        render_desc(&desc, &Opts { integrator: Some("ltc"), spp: Some(64), resolution: None, ..Default::default() });
    assert!(warned(
        &ours,
        "ltc: material \"disney\" (no Lambertian-plus-GGX form) is lit by directlighting's estimator"
    ));
    let reference = reference("disney-reflection-dl");
    let ratio = 64.0 / reference_spp("disney-reflection-dl");
    assert_matches_reference("disney-reflection (ltc, 64 spp)", &ours, &reference, ratio, 0.01);
    assert_regions_match("disney-reflection (ltc, 64 spp)", &ours, &reference, ratio, 8);
}

/// Every analytic integrator gives a finite image of each new material and names the material
/// whose lobes it leaves to directlighting's estimator: `ratio` (no LTC form, area light),
/// `silhouette` (hair's and fourier's transmission under the environment; Disney's reflection
/// lobes it projects onto SH, as plastic's: `silhouette::glossy`'s unit test), `shexp`
/// (non-Lambertian lobes under the environment). No material is ever rendered as matte.
#[test]
fn analytic_integrators_name_the_materials_they_fall_back_for() {
    let cases: [(&str, &str, &[&str]); 5] = [
        ("disney-reflection", "ratio", &["ratio: material \"disney\""]),
        ("hair", "ratio", &["ratio: material \"hair\""]),
        ("hair", "silhouette", &["silhouette: material \"hair\" (non-specular transmission)"]),
        ("fourier", "shexp", &["shexp: material \"fourier\" (non-Lambertian lobes)"]),
        (
            "subsurface",
            "shexp",
            &["material \"subsurface\": its subsurface scattering", "shexp: material \"subsurface\""],
        ),
    ];
    for (scene_name, integrator, wants) in cases {
        let r = render_scene(scene_name, integrator, 4, |_| {});
        assert!(r.image.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{scene_name} {integrator}");
        for want in wants {
            assert!(warned(&r, want), "{scene_name} {integrator}: no \"{want}\" in {:?}", r.warnings);
        }
        assert!(!r.warnings.iter().any(|w| w.contains("rendering it as \"matte\"")), "{:?}", r.warnings);
    }
}

/// `sheared-ao` computes ambient occlusion: its image does not depend on the materials, so the
/// scene with every object made matte renders the same bits.
#[test]
fn sheared_ao_is_independent_of_the_new_materials() {
    for scene_name in ["disney-transmission", "hair", "fourier", "subsurface"] {
        let with = render_scene(scene_name, "sheared-ao", 4, |_| {});
        let matte = render_scene(scene_name, "sheared-ao", 4, |t| {
            *t = t
                .lines()
                .map(|l| if l.trim_start().starts_with("Material") { "  Material \"matte\"" } else { l })
                .collect::<Vec<_>>()
                .join("\n");
        });
        assert_same(&with.image.data, &matte.image.data, scene_name);
    }
}
