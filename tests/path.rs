//! `path` and `whitted` end to end: against the real pbrt-v3's renders of public scenes that ask
//! for them (`tests/data/path-references/`), in a closed white furnace where the answer is a
//! geometric series, bit-identical across threads and crops, finite on the stiff scenes, and
//! the fallback of the pbrt-v3 integrators penumbra does not implement.

mod common;
use common::*;
use penumbra_core::image::Image;

/// `tests/data/path-references/timings.tsv`: (scene under scenes/public, spp, render resolution).
fn reference_case(name: &str) -> (String, f64, f64) {
    let tsv = std::fs::read_to_string(root().join("tests/data/path-references/timings.tsv")).unwrap();
    let line = tsv.lines().find(|l| l.starts_with(&format!("{name}\t"))).unwrap_or_else(|| panic!("{name} timing"));
    let f: Vec<&str> = line.split('\t').collect();
    (f[1].to_string(), f[3].parse().unwrap(), f[4].parse().unwrap())
}

/// Renders the public scene of reference `name` at 64×64 with `integrator`, its own sampler
/// and a box filter (as the reference script renders it for pbrt-v3), and compares: the image
/// mean within 1 %, per value within the noise, and the means of 8×8-pixel regions.
fn check(name: &str, integrator: &str, spp: u32) {
    let (rel, ref_spp, ref_res) = reference_case(name);
    let mut desc = penumbra_parser::parse_file(&scene(&format!("public/{rel}"))).unwrap().scene;
    desc.filter = penumbra_parser::Entity::default_of("box");
    let ours = render_desc(&desc, &Opts { integrator: Some(integrator), spp: Some(spp), ..Default::default() });
    let reference: Image = image_rgb(&format!("tests/data/path-references/{name}.exr"));
    let per_pixel = ref_spp * (ref_res / 64.0).powi(2);
    let label = format!("{name} ({integrator}, {spp} spp)");
    assert_matches_reference(&label, &ours, &reference, spp as f64 / per_pixel, 0.01);
    assert_regions_match(&label, &ours, &reference, spp as f64 / per_pixel, 8);
}

fn image_rgb(rel: &str) -> Image {
    penumbra_core::image::read(root().join(rel)).unwrap().select_channels(&["R", "G", "B"]).unwrap()
}

#[test]
fn path_matches_pbrt_v3_cornell_box() {
    check("cornell-box", "path", 256);
}

#[test]
fn path_matches_pbrt_v3_killeroo() {
    check("killeroo-simple", "path", 256);
}

#[test]
fn path_matches_pbrt_v3_glass() {
    check("glass-path", "path", 128);
}

#[test]
fn whitted_matches_pbrt_v3_glass_and_mirror() {
    check("glass-whitted", "whitted", 64);
    check("mirror-whitted", "whitted", 64);
}

/// The `windy` bump map on a tessellated sphere. It was 1.0 % (path) and 1.4 % (whitted) below
/// pbrt-v3 while penumbra's noise used its own permutation table: a different noise pattern
/// bumps the sphere differently; with Perlin's table (pbrt-v3's) the means agree to 0.03 %.
#[test]
fn path_and_whitted_match_pbrt_v3_bump_map() {
    check("bump-whitted", "whitted", 64);
    check("bump-path", "path", 128);
}

/// The inside of a closed cube whose walls emit `L` = 1 (both sides) and reflect with albedo
/// `a` (matte), seen from its centre: radiance L/(1−a) everywhere after infinitely many
/// bounces; a path of at most `maxdepth` bounces sees L·(1 + a + … + a^maxdepth).
fn furnace_scene(a: f32) -> String {
    format!(
        "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" [100]\n\
         Film \"image\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n\
         Sampler \"random\" \"integer pixelsamples\" [128]\nWorldBegin\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" \"true\"\n\
         Material \"matte\" \"rgb Kd\" [{a} {a} {a}]\n\
         Shape \"trianglemesh\" \"point P\" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1]\n\
         \"integer indices\" [0 1 2 0 2 3  4 6 5 4 7 6  0 4 5 0 5 1  3 2 6 3 6 7  0 3 7 0 7 4  1 5 6 1 6 2]\nWorldEnd\n"
    )
}

/// The image mean of the first channel and its standard error (pixels are independent under
/// the random sampler; the channels of a grey scene are not, so one channel is used).
fn mean_and_error(r: &Render) -> (f64, f64) {
    let n = (r.image.data.len() / 3) as f64;
    let m = r.image.data.iter().step_by(3).map(|v| *v as f64).sum::<f64>() / n;
    let var = r.variance.data.iter().step_by(3).map(|v| *v as f64).sum::<f64>() / (n * n);
    (m, var.sqrt())
}

#[test]
fn path_white_furnace_is_the_geometric_series() {
    for a in [0.5f64, 0.8] {
        // maxdepth 10000: only Russian roulette ends the paths (an a^10001 tail is below 1e-900).
        for depth in [0u32, 1, 2, 5, 10000] {
            let expected = (1.0 - a.powi(depth as i32 + 1)) / (1.0 - a);
            let strategies: &[&str] = if depth == 5 { &["spatial", "uniform", "power"] } else { &["uniform"] };
            for strategy in strategies {
                let params = [format!("maxdepth={depth}"), format!("lightsamplestrategy={strategy}")];
                let params: Vec<&str> = params.iter().map(String::as_str).collect();
                let r = render_text(
                    &furnace_scene(a as f32),
                    &Opts {
                        integrator: Some("path"),
                        params: &params,
                        resolution: None,
                        seed: 7,
                        ..Default::default()
                    },
                );
                let (m, se) = mean_and_error(&r);
                eprintln!("furnace a={a} maxdepth={depth} {strategy}: {m:.5} ± {se:.5}, expected {expected:.5}");
                // The 4σ band must exclude one bounce more or less (the next term is a^(depth+1));
                // with Russian roulette only, 1 % of the answer.
                let next = if depth > 60 { 0.04 * expected } else { a.powi(depth as i32 + 1) };
                assert!(4.0 * se < next, "a={a} maxdepth={depth}: error {se} too large");
                assert!(
                    (m - expected).abs() < 4.0 * se + 1e-4 * expected,
                    "a={a} maxdepth={depth} {strategy}: {m} ± {se}, expected {expected}"
                );
            }
        }
    }
}

/// `whitted` in the same furnace: emission plus one bounce of direct light, L·(1 + a), at any
/// `maxdepth` (matte has no specular lobe to follow).
#[test]
fn whitted_white_furnace_is_one_bounce() {
    for (a, depth) in [(0.5f64, 1u32), (0.8, 5)] {
        let params = [format!("maxdepth={depth}")];
        let params: Vec<&str> = params.iter().map(String::as_str).collect();
        let r = render_text(
            &furnace_scene(a as f32),
            &Opts { integrator: Some("whitted"), params: &params, resolution: None, seed: 3, ..Default::default() },
        );
        let (m, se) = mean_and_error(&r);
        // The 4σ band must exclude a second bounce (a²).
        assert!(4.0 * se < a * a, "a={a}: error {se} too large");
        assert!((m - (1.0 + a)).abs() < 4.0 * se + 1e-4, "a={a}: {m} ± {se}, expected {}", 1.0 + a);
    }
}

/// Bit-identical images whatever the thread count and crop, with the spatial light
/// distribution (four light triangles) and both global samplers.
#[test]
fn path_and_whitted_are_deterministic() {
    let path = scene("suite/ltc/two-lights-metal.pbrt");
    for (integrator, sampler) in [("path", "halton"), ("path", "sobol"), ("whitted", "halton")] {
        assert_deterministic(40, 36, |threads, crop| {
            render_path(
                &path,
                &Opts {
                    integrator: Some(integrator),
                    spp: Some(4),
                    resolution: Some((40, 36)),
                    threads,
                    seed: 5,
                    crop,
                    sampler: Some(sampler),
                    ..Default::default()
                },
            )
        });
    }
}

/// Every stiff scene renders finite, with no sample replaced for being non-finite or negative.
#[test]
fn path_and_whitted_are_finite_on_stiff_scenes() {
    for name in STIFF_SCENES {
        for integrator in ["path", "whitted"] {
            let r = render_path(
                &scene(&format!("suite/stiff/{name}.pbrt")),
                &Opts { integrator: Some(integrator), spp: Some(16), resolution: Some((32, 32)), ..Default::default() },
            );
            assert!(r.image.data.iter().all(|v| v.is_finite()), "{integrator} {name}: non-finite values");
            assert!(
                !r.warnings.iter().any(|w| w.contains("NaN, infinite or negative")),
                "{integrator} {name}: {:?}",
                r.warnings
            );
            assert!(mean(&r.image) > 0.0, "{integrator} {name}: black image");
        }
    }
}

/// pbrt-v3's `"integer pixelbounds"`: pixels outside take no samples (black under a box
/// filter), pixels inside are exactly those of the full render.
#[test]
fn pixelbounds_limits_the_sampled_pixels() {
    let body = std::fs::read_to_string(scene("suite/ltc/quad-cube.pbrt")).unwrap();
    let old = "Integrator \"directlighting\" \"string strategy\" [ \"all\" ] \"integer maxdepth\" [ 1 ]";
    assert!(body.contains(old));
    for integrator in ["path", "whitted", "directlighting"] {
        let render = |extra: &str| {
            let text = body.replace(old, &format!("Integrator \"{integrator}\" {extra}"));
            let mut desc = penumbra_parser::parse_str(&text, "<test>", Some(&root())).unwrap().scene;
            desc.filter = penumbra_parser::Entity::default_of("box");
            render_desc(&desc, &Opts { spp: Some(4), resolution: Some((24, 20)), ..Default::default() })
        };
        let full = render("");
        let part = render("\"integer pixelbounds\" [5 17 3 11]");
        assert!(!part.warnings.iter().any(|w| w.contains("pixelbounds")), "{:?}", part.warnings);
        for y in 0..20 {
            for x in 0..24 {
                let inside = (5..17).contains(&x) && (3..11).contains(&y);
                for c in 0..3 {
                    let i = (y * 24 + x) * 3 + c;
                    let want = if inside { full.image.data[i] } else { 0.0 };
                    assert_eq!(part.image.data[i].to_bits(), want.to_bits(), "{integrator} pixel ({x}, {y})");
                }
            }
        }
        assert!(mean(&part.image) > 0.0, "{integrator}: nothing rendered inside the bounds");
    }
}

/// Scenes naming a pbrt-v3 integrator penumbra does not implement render with `path`, keeping
/// their `maxdepth`, and say so once; `path` and `whitted` themselves no longer fall back; `-i`
/// overrides the scene's choice.
#[test]
fn unimplemented_integrators_fall_back_to_path() {
    let body = std::fs::read_to_string(scene("suite/ltc/quad-cube.pbrt")).unwrap();
    let with = |name: &str| {
        let text = body.replace(
            "Integrator \"directlighting\" \"string strategy\" [ \"all\" ] \"integer maxdepth\" [ 1 ]",
            &format!("Integrator \"{name}\" \"integer maxdepth\" [ 3 ]"),
        );
        assert!(text.contains(&format!("Integrator \"{name}\"")));
        text
    };
    let opts = Opts { spp: Some(4), resolution: Some((24, 24)), ..Default::default() };
    let base = render_text(&with("path"), &opts);
    assert!(!base.warnings.iter().any(|w| w.contains("not implemented")), "{:?}", base.warnings);
    let whitted = render_text(&with("whitted"), &opts);
    assert!(!whitted.warnings.iter().any(|w| w.contains("not implemented")), "{:?}", whitted.warnings);
    assert_ne!(whitted.image.data, base.image.data, "whitted renders as itself");
    let depth5 = render_text(&with("path").replace("[ 3 ]", "[ 5 ]"), &opts);
    assert_ne!(depth5.image.data, base.image.data, "maxdepth changes the image");
    for name in ["volpath", "bdpt", "mlt", "sppm"] {
        let r = render_text(&with(name), &opts);
        let fallbacks: Vec<_> = r.warnings.iter().filter(|w| w.contains("not implemented")).collect();
        assert_eq!(fallbacks.len(), 1, "{name}: {:?}", r.warnings);
        assert!(fallbacks[0].contains(name) && fallbacks[0].contains("\"path\""), "{}", fallbacks[0]);
        assert_eq!(r.image.data, base.image.data, "{name}: same image as path with maxdepth 3");
        let ao = render_text(&with(name), &Opts { integrator: Some("ambientocclusion"), ..opts });
        assert!(!ao.warnings.iter().any(|w| w.contains("not implemented")), "{:?}", ao.warnings);
        assert_ne!(ao.image.data, base.image.data, "-i must override the scene's integrator");
    }
}
