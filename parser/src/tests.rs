//! Interpreter tests: directives, parameter types, graphics state, errors.

use crate::*;
use std::path::Path;

fn parse(text: &str) -> ParseOutput {
    match parse_str(text, "test.pbrt", None) {
        Ok(o) => o,
        Err(e) => panic!("unexpected error:\n{e}"),
    }
}

fn parse_err(text: &str) -> Diagnostic {
    match parse_str(text, "test.pbrt", None) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            assert!(e.is_error());
            e
        }
    }
}

/// Asserts an error at `line:col` whose message contains `needle`, with its source line and caret.
fn assert_err(text: &str, line: u32, col: u32, needle: &str) {
    let e = parse_err(text);
    let loc = e.loc.clone().unwrap_or_else(|| panic!("unlocated: {e}"));
    assert_eq!((loc.line, loc.column), (line, col), "{e}");
    assert!(e.message.contains(needle), "expected {needle:?} in: {e}");
    let src = e.source_line.clone().unwrap_or_else(|| panic!("no source line: {e}"));
    assert_eq!(Some(src.as_str()), text.split('\n').nth(line as usize - 1));
    assert!(e.to_string().contains(&format!("test.pbrt:{line}:{col}")), "{e}");
}

fn world(body: &str) -> String {
    format!("WorldBegin\n{body}\nWorldEnd\n")
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
}

fn tmpdir(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-parser-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn defaults_when_directives_are_absent() {
    let s = parse("WorldBegin WorldEnd").scene;
    assert_eq!(s.camera.entity.kind, "perspective");
    assert_eq!(s.film.kind, "image");
    assert_eq!(s.sampler.kind, "halton");
    assert_eq!(s.filter.kind, "box");
    assert_eq!(s.integrator.kind, "path");
    assert_eq!(s.accelerator.kind, "bvh");
    assert!(s.film.loc.is_builtin());
    assert_eq!(s.transform_times, (0.0, 1.0));
}

#[test]
fn options_directives_are_recorded() {
    let s = parse(
        "Film \"image\" \"integer xresolution\" 32\nSampler \"sobol\" \"integer pixelsamples\" [4]\n\
         PixelFilter \"gaussian\"\nIntegrator \"directlighting\"\nAccelerator \"kdtree\"\nTransformTimes 0.25 0.75\n\
         Camera \"orthographic\"\nWorldBegin\nWorldEnd",
    )
    .scene;
    assert_eq!(s.film.params.get_one_int("xresolution", 0), 32);
    assert_eq!((s.film.loc.line, s.film.loc.column), (1, 1));
    assert_eq!(s.sampler.kind, "sobol");
    assert_eq!(s.sampler.params.get_ints("pixelsamples"), Some(&[4][..]));
    assert_eq!(s.filter.kind, "gaussian");
    assert_eq!(s.integrator.kind, "directlighting");
    assert_eq!(s.accelerator.kind, "kdtree");
    assert_eq!(s.transform_times, (0.25, 0.75));
    assert_eq!(s.camera.entity.kind, "orthographic");
    assert_eq!(s.camera.camera_from_world.start_time, 0.25);
}

#[test]
fn every_parameter_type() {
    let s = parse(&world(
        "Shape \"x\" \"integer i\" [1 -2] \"float f\" 0.5 \"point2 p2\" [1 2] \"vector2 v2\" [3 4]\n\
         \"point3 p3\" [1 2 3] \"point p\" [4 5 6] \"vector3 v3\" [1 0 0] \"vector v\" [0 1 0] \"normal n\" [0 0 1]\n\
         \"rgb c\" [.1 .2 .3] \"color c2\" [1 1 1] \"xyz x\" [1 2 3] \"blackbody b\" [6500 2] \"blackbody b1\" 3000\n\
         \"spectrum s\" [400 1 500 2] \"bool t\" \"true\" \"bool fl\" [\"false\" \"true\"] \"string str\" [\"a\" \"b\"]",
    ));
    let ps = &s.scene.shapes[0].entity.params;
    assert_eq!(ps.get_ints("i"), Some(&[1, -2][..]));
    assert_eq!(ps.get_one_float("f", 0.0), 0.5);
    assert_eq!(ps.get_one_point2("p2", [0.0; 2]), [1.0, 2.0]);
    assert_eq!(ps.get_one_vector2("v2", [0.0; 2]), [3.0, 4.0]);
    assert_eq!(ps.get_point3s("p3"), Some(&[[1.0, 2.0, 3.0]][..]));
    assert_eq!(ps.get_one_point3("p", [0.0; 3]), [4.0, 5.0, 6.0]);
    assert_eq!(ps.get_one_vector3("v3", [0.0; 3]), [1.0, 0.0, 0.0]);
    assert_eq!(ps.get_one_vector3("v", [0.0; 3]), [0.0, 1.0, 0.0]);
    assert_eq!(ps.get_one_normal("n", [0.0; 3]), [0.0, 0.0, 1.0]);
    assert_eq!(ps.get_spectrum("c"), Some(&SpectrumValue::Rgb(vec![0.1, 0.2, 0.3])));
    assert_eq!(ps.get_spectrum("c2"), Some(&SpectrumValue::Rgb(vec![1.0, 1.0, 1.0])));
    assert_eq!(ps.get_spectrum("x"), Some(&SpectrumValue::Xyz(vec![1.0, 2.0, 3.0])));
    assert_eq!(ps.get_spectrum("b"), Some(&SpectrumValue::Blackbody(vec![6500.0, 2.0])));
    assert_eq!(ps.get_spectrum("b1"), Some(&SpectrumValue::Blackbody(vec![3000.0, 1.0])));
    assert_eq!(ps.get_spectrum("s"), Some(&SpectrumValue::Sampled(vec![400.0, 1.0, 500.0, 2.0])));
    assert!(ps.get_one_bool("t", false));
    assert_eq!(ps.get_bools("fl"), Some(&[false, true][..]));
    assert_eq!(ps.get_strings("str"), Some(&["a".to_string(), "b".to_string()][..]));
    assert!(ps.report_unused("shape").is_empty());
    // The lone blackbody temperature is warned about, at the parameter.
    let w = s.warnings.iter().find(|w| w.message.contains("blackbody")).expect("blackbody warning");
    assert_eq!(w.loc.as_ref().unwrap().line, 4);
}

#[test]
fn parameter_locations_and_unused_report() {
    let text = world("Shape \"sphere\"\n    \"float radus\" [ 2 ]");
    let out = parse_str(&text, "unused-report.pbrt", None).unwrap();
    let shape = &out.scene.shapes[0];
    assert_eq!(shape.entity.params.get_one_float("radius", 1.0), 1.0);
    let unused = shape.entity.params.report_unused("shape \"sphere\"");
    assert_eq!(unused.len(), 1);
    let d = unused[0].clone().with_source();
    assert!(d.message.contains("radus"), "{d}");
    let loc = d.loc.clone().unwrap();
    assert_eq!((&*loc.file, loc.line, loc.column), ("unused-report.pbrt", 3, 5));
    assert_eq!(d.source_line.as_deref(), Some("    \"float radus\" [ 2 ]"));
    assert!(d.to_string().contains("unused-report.pbrt:3:5") && d.to_string().contains("    ^"), "{d}");
}

#[test]
fn later_parameter_of_same_name_wins() {
    let s = parse(&world("Shape \"sphere\" \"float radius\" 1 \"float radius\" 3")).scene;
    assert_eq!(s.shapes[0].entity.params.params.len(), 1);
    assert_eq!(s.shapes[0].entity.params.get_one_float("radius", 0.0), 3.0);
}

#[test]
fn parameter_type_errors_are_located() {
    assert_err(&world("Shape \"s\" \"float x\" [\"a\"]"), 2, 22, "expected numeric values");
    assert_err(&world("Shape \"s\" \"integer n\" [1.5]"), 2, 24, "expected an integer");
    assert_err(&world("Shape \"s\" \"integer n\" [2147483648]"), 2, 24, "out of range");
    assert_err(&world("Shape \"s\" \"float n\" [1e999]"), 2, 22, "out of range");
    assert_err(&world("Shape \"s\" \"rgb Kd\" [1 2]"), 2, 11, "multiple of 3");
    assert_err(&world("Shape \"s\" \"point3 P\" [1 2 3 4]"), 2, 11, "multiple of 3");
    assert_err(&world("Shape \"s\" \"bool b\" [1]"), 2, 21, "quoted");
    assert_err(&world("Shape \"s\" \"bool b\" true"), 2, 20, "quoted");
    assert_err(&world("Shape \"s\" \"bool b\" \"yes\""), 2, 20, "\"true\" or \"false\"");
    assert_err(&world("Shape \"s\" \"floot x\" [1]"), 2, 11, "unknown parameter type \"floot\"");
    assert_err(&world("Shape \"s\" \"float\" [1]"), 2, 11, "type name");
    assert_err(&world("Shape \"s\" \"string s\" [1]"), 2, 23, "quoted string");
    assert_err(&world("Shape \"s\" \"float x\" [1 \"a\"]"), 2, 24, "mixed");
    assert_err(&world("Shape \"s\" \"spectrum s\" [400 1 500]"), 2, 11, "pairs");
    assert_err(&world("Shape \"s\" \"blackbody s\" [1 2 3]"), 2, 11, "pairs");
    assert_err(&world("Shape \"s\" \"texture t\" [\"a\" \"b\"]"), 2, 11, "exactly one");
    assert_err(&world("Shape \"s\" \"float x\""), 3, 1, "expected a number");
    assert_err(&world("Shape \"s\" \"float x\" [1 [2]]"), 2, 24, "unexpected '['");
}

#[test]
fn structural_errors_are_located() {
    assert_err("WorldBegin\nShape \"s\" \"float x\" [1 2", 2, 21, "unclosed '['");
    assert_err("WorldBegin\nShape \"s", 2, 7, "end of file");
    assert_err("WorldBegin\nShape \"s\n\"", 2, 7, "newline");
    assert_err("WorldBegin\nShape", 2, 6, "expected a quoted string");
    assert_err("WorldBegin\nTranslate 1 2", 2, 14, "expected a number");
    assert_err("WorldBegin\nTranslate 1 x 2", 2, 13, "expected a number");
    assert_err("Frobnicate 1", 1, 1, "unknown directive");
    assert_err("WorldBegin\n\"x\"", 2, 1, "expected a directive");
    assert_err("WorldBegin\n]", 2, 1, "expected a directive");
    assert_err("Transform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0]", 1, 41, "expected a number");
    assert_err("Transform 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", 1, 11, "expected '['");
    assert_err("Transform [0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0]", 1, 1, "singular");
    assert_err("Scale 1 0 1", 1, 1, "singular");
    assert_err("Rotate 30 0 0 0", 1, 1, "axis");
    assert_err("LookAt 0 0 0 0 1 0 0 1 0", 1, 1, "parallel");
    assert_err("ActiveTransform Sometimes", 1, 17, "StartTime, EndTime or All");
    assert_err("WorldBegin\nCamera \"perspective\"", 2, 1, "options cannot be set");
    assert_err("WorldBegin\nWorldBegin", 2, 1, "options cannot be set");
    assert_err("Film \"image\"\nShape \"sphere\"", 2, 1, "only allowed inside the world block");
    assert_err("WorldBegin\nWorldEnd\nShape \"sphere\"", 3, 1, "after WorldEnd");
    assert_err("WorldBegin\nTexture \"t\" \"vector\" \"constant\"", 2, 13, "unknown texture type");
}

#[test]
fn pbrt_v4_directives_warn_and_are_skipped() {
    let out = parse(
        "ColorSpace \"srgb\"\nOption \"bool disablepixeljitter\" true\nFilm \"rgb\"\n\
         WorldBegin\nAttribute \"shape\" \"float radius\" [2]\nShape \"sphere\" \"point3 c\" [0 0 0]\nWorldEnd",
    );
    let v4: Vec<_> = out.warnings.iter().filter(|w| w.message.contains("pbrt-v4")).collect();
    assert_eq!(v4.len(), 3);
    assert_eq!(v4[1].loc.as_ref().unwrap().line, 2);
    assert_eq!(out.scene.film.kind, "rgb");
    assert_eq!(out.scene.shapes.len(), 1);
}

#[test]
fn ctm_translate_scale_and_lookat() {
    let s = parse(&world("Translate 1 2 3\nScale -1 1 1\nShape \"sphere\"")).scene;
    let t = s.shapes[0].render_from_object.start;
    // Scale applies first (object space), then the translation.
    assert!(close(t.apply_point([1.0, 0.0, 0.0]), [0.0, 2.0, 3.0]));
    assert!(t.swaps_handedness());
    let s = parse("LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\nWorldEnd").scene;
    let c = &s.camera;
    assert!(close(c.camera_from_world.start.apply_point([0.0, 0.0, -5.0]), [0.0; 3]));
    assert!(close(c.camera_from_world.start.apply_point([0.0, 0.0, 1.0]), [0.0, 0.0, 6.0]));
    assert!(close(c.world_from_camera.start.apply_point([0.0; 3]), [0.0, 0.0, -5.0]));
    // WorldBegin resets the CTM.
    let s = parse("Translate 5 0 0\nWorldBegin\nShape \"sphere\"").scene;
    assert!(close(s.shapes[0].render_from_object.start.apply_point([0.0; 3]), [0.0; 3]));
}

#[test]
fn transform_matrices_are_column_major() {
    let s = parse(&world("Transform [1 0 0 0  0 1 0 0  0 0 1 0  7 8 9 1]\nShape \"a\"\nConcatTransform [2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1]\nShape \"b\"")).scene;
    assert!(close(s.shapes[0].render_from_object.start.apply_point([0.0; 3]), [7.0, 8.0, 9.0]));
    assert!(close(s.shapes[1].render_from_object.start.apply_point([1.0, 1.0, 1.0]), [9.0, 10.0, 11.0]));
    let s = parse(&world("Translate 1 0 0\nIdentity\nRotate 90 0 0 1\nShape \"a\"")).scene;
    assert!(close(s.shapes[0].render_from_object.start.apply_point([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]));
}

#[test]
fn active_transform_makes_animated_pairs() {
    let s = parse(&world(
        "ActiveTransform StartTime\nTranslate 1 0 0\nActiveTransform EndTime\nTranslate 0 1 0\nActiveTransform All\nShape \"sphere\"",
    ))
    .scene;
    let t = s.shapes[0].render_from_object;
    assert!(t.is_animated());
    assert!(close(t.start.apply_point([0.0; 3]), [1.0, 0.0, 0.0]));
    assert!(close(t.end.apply_point([0.0; 3]), [0.0, 1.0, 0.0]));
}

#[test]
fn attribute_and_transform_stacks() {
    let s = parse(&world(
        "AttributeBegin\nTranslate 1 0 0\nReverseOrientation\nMaterial \"plastic\"\nShape \"a\"\nAttributeEnd\n\
         TransformBegin\nTranslate 0 1 0\nMaterial \"metal\"\nTransformEnd\nShape \"b\"",
    ))
    .scene;
    let (a, b) = (&s.shapes[0], &s.shapes[1]);
    assert!(a.reverse_orientation && !b.reverse_orientation);
    assert!(close(a.render_from_object.start.apply_point([0.0; 3]), [1.0, 0.0, 0.0]));
    // TransformEnd restores only the CTM: the material set inside it stays.
    assert!(close(b.render_from_object.start.apply_point([0.0; 3]), [0.0; 3]));
    assert_eq!(s.materials[a.material.unwrap()].entity.kind, "plastic");
    assert_eq!(s.materials[b.material.unwrap()].entity.kind, "metal");
}

#[test]
fn unmatched_ends_and_open_blocks_warn() {
    let out = parse(&world("AttributeEnd\nTransformEnd\nAttributeBegin\nTransformBegin"));
    let msgs: Vec<&str> = out.warnings.iter().map(|w| w.message.as_str()).collect();
    assert!(msgs.iter().any(|m| m.contains("unmatched AttributeEnd")), "{msgs:?}");
    assert!(msgs.iter().any(|m| m.contains("unmatched TransformEnd")), "{msgs:?}");
    assert!(msgs.iter().any(|m| m.contains("missing AttributeEnd")), "{msgs:?}");
    assert!(msgs.iter().any(|m| m.contains("missing TransformEnd")), "{msgs:?}");
    assert!(out.warnings.iter().all(|w| w.loc.is_some() && w.source_line.is_some()));
}

#[test]
fn attribute_nesting_is_capped() {
    let text = format!("WorldBegin\n{}", "AttributeBegin ".repeat(MAX_NESTING + 5));
    let e = parse_err(&text);
    assert!(e.message.contains("nested"), "{e}");
    assert_eq!(e.loc.unwrap().column as usize, MAX_NESTING * 15 + 1);
}

#[test]
fn named_coordinate_systems() {
    let s = parse(
        "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\nTranslate 3 0 0\nCoordinateSystem \"here\"\n\
         Identity\nCoordSysTransform \"here\"\nShape \"a\"\nCoordSysTransform \"camera\"\nShape \"b\"\n\
         CoordSysTransform \"world\"\nShape \"c\"\nCoordSysTransform \"nowhere\"",
    );
    let sh = &s.scene.shapes;
    assert!(close(sh[0].render_from_object.start.apply_point([0.0; 3]), [3.0, 0.0, 0.0]));
    // "camera" is the camera-to-world transform: the camera-space origin is the eye.
    assert!(close(sh[1].render_from_object.start.apply_point([0.0; 3]), [0.0, 0.0, -5.0]));
    assert!(close(sh[2].render_from_object.start.apply_point([0.0; 3]), [0.0; 3]));
    assert!(s.warnings.iter().any(|w| w.message.contains("nowhere")));
}

#[test]
fn materials_named_and_none() {
    let s = parse(&world(
        "Shape \"default\"\nMaterial \"none\"\nShape \"iface\"\nMaterial \"\"\nShape \"iface2\"\n\
         MakeNamedMaterial \"gold\" \"string type\" \"metal\" \"float roughness\" 0.1\nShape \"still-iface\"\n\
         NamedMaterial \"gold\"\nShape \"gold\"\nMaterial \"plastic\"\nShape \"plastic\"",
    ))
    .scene;
    let m = |i: usize| s.shapes[i].material.map(|k| s.materials[k].entity.kind.as_str());
    assert_eq!(m(0), Some("matte"));
    assert!(s.materials[s.shapes[0].material.unwrap()].entity.loc.is_builtin());
    assert_eq!((m(1), m(2), m(3)), (None, None, None));
    assert_eq!(m(4), Some("metal"));
    let gold = &s.materials[s.shapes[4].material.unwrap()];
    assert_eq!(gold.name.as_deref(), Some("gold"));
    assert_eq!(gold.entity.params.get_one_float("roughness", 0.0), 0.1);
    // "type" was consumed by the parser.
    assert!(gold.entity.params.report_unused("material").is_empty());
    assert_eq!(m(5), Some("plastic"));
}

#[test]
fn material_errors() {
    assert_err(&world("MakeNamedMaterial \"m\" \"float roughness\" 1"), 2, 1, "string type");
    assert_err(&world("NamedMaterial \"nope\""), 2, 15, "no material named \"nope\"");
    // Named materials are scoped by AttributeBegin/End, as in pbrt-v3.
    assert_err(
        &world("AttributeBegin\nMakeNamedMaterial \"m\" \"string type\" \"matte\"\nAttributeEnd\nNamedMaterial \"m\""),
        5,
        15,
        "no material named",
    );
}

#[test]
fn texture_scoping_and_resolution() {
    let s = parse(&world(
        "Texture \"t\" \"float\" \"constant\" \"float value\" 1\n\
         AttributeBegin\nTexture \"t\" \"color\" \"checkerboard\"\nTexture \"u\" \"spectrum\" \"scale\" \"texture tex1\" \"t\"\n\
         Material \"matte\" \"texture Kd\" \"t\" \"texture sigma\" \"t\"\nShape \"a\"\nAttributeEnd\n\
         Material \"matte\" \"texture Kd\" \"t\" \"texture bump\" \"u\"\nShape \"b\"",
    ));
    let sc = &s.scene;
    assert_eq!(sc.textures.len(), 3);
    assert_eq!(sc.textures[1].kind, TextureKind::Spectrum);
    // Inside the block both namespaces hold a "t".
    let inner = &sc.materials[sc.shapes[0].material.unwrap()].entity.params;
    assert_eq!(inner.get_texture("Kd"), Some(&TextureRef { name: "t".into(), float: Some(0), spectrum: Some(1) }));
    // A texture's own texture parameters resolve where it is defined.
    assert_eq!(sc.textures[2].entity.params.get_texture("tex1").unwrap().spectrum, Some(1));
    // After AttributeEnd the spectrum "t" and "u" are gone.
    let outer = &sc.materials[sc.shapes[1].material.unwrap()].entity.params;
    assert_eq!(outer.get_texture("Kd"), Some(&TextureRef { name: "t".into(), float: Some(0), spectrum: None }));
    assert_eq!(outer.get_texture("bump"), Some(&TextureRef { name: "u".into(), float: None, spectrum: None }));
    let w = s.warnings.iter().find(|w| w.message.contains("no texture named \"u\"")).expect("warning");
    assert_eq!(w.loc.as_ref().unwrap().line, 9);
}

#[test]
fn texture_transform_is_the_ctm() {
    let s = parse(&world("Scale 2 2 2\nTexture \"t\" \"float\" \"checkerboard\"")).scene;
    assert!(close(s.textures[0].render_from_texture.start.apply_point([1.0, 1.0, 1.0]), [2.0, 2.0, 2.0]));
}

#[test]
fn lights_and_area_lights() {
    let s = parse(&world(
        "Translate 0 1 0\nLightSource \"point\" \"rgb I\" [1 1 1]\nAttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2 2 2]\n\
         Shape \"a\"\nShape \"b\"\nAreaLightSource \"area\"\nShape \"c\"\nAttributeEnd\nShape \"d\"",
    ))
    .scene;
    assert_eq!(s.lights.len(), 1);
    assert!(close(s.lights[0].render_from_light.start.apply_point([0.0; 3]), [0.0, 1.0, 0.0]));
    assert_eq!(s.area_lights.len(), 2);
    let al: Vec<Option<usize>> = s.shapes.iter().map(|x| x.area_light).collect();
    assert_eq!(al, [Some(0), Some(0), Some(1), None]);
    assert_eq!(s.area_lights[1].kind, "area");
}

#[test]
fn animated_area_light_is_dropped_with_warning() {
    let out = parse(&world("AreaLightSource \"diffuse\"\nActiveTransform EndTime\nTranslate 1 0 0\nShape \"sphere\""));
    assert_eq!(out.scene.shapes[0].area_light, None);
    assert!(out.warnings.iter().any(|w| w.message.contains("animated shape")));
}

#[test]
fn instancing() {
    let out = parse(&world(
        "ObjectBegin \"tree\"\nTranslate 1 0 0\nAreaLightSource \"diffuse\"\nShape \"sphere\"\nShape \"disk\"\nObjectEnd\n\
         Shape \"after\"\nTranslate 0 5 0\nObjectInstance \"tree\"\nObjectInstance \"tree\"",
    ));
    let s = &out.scene;
    assert_eq!(s.instance_definitions.len(), 1);
    let def = &s.instance_definitions[0];
    assert_eq!(def.name, "tree");
    assert_eq!(def.shapes.len(), 2);
    assert!(def.shapes.iter().all(|x| x.area_light.is_none()));
    assert!(out.warnings.iter().any(|w| w.message.contains("area lights not supported with object instancing")));
    // ObjectEnd closes the attribute block ObjectBegin opened: "after" has no translation and no area light.
    assert_eq!(s.shapes.len(), 1);
    assert!(s.shapes[0].area_light.is_none());
    assert!(close(s.shapes[0].render_from_object.start.apply_point([0.0; 3]), [0.0; 3]));
    assert_eq!(s.instances.len(), 2);
    assert_eq!(s.instances[1].definition, 0);
    assert!(close(s.instances[0].render_from_instance.start.apply_point([0.0; 3]), [0.0, 5.0, 0.0]));
}

#[test]
fn instancing_errors() {
    assert_err(&world("ObjectBegin \"a\"\nObjectBegin \"b\""), 3, 1, "inside another object");
    assert_err(&world("ObjectInstance \"ghost\""), 2, 16, "no object named \"ghost\"");
    assert_err(&world("ObjectBegin \"a\"\nObjectInstance \"a\""), 3, 1, "inside an object definition");
    let out = parse(&world("ObjectEnd"));
    assert!(out.warnings.iter().any(|w| w.message.contains("ObjectEnd outside")));
}

#[test]
fn media_are_recorded() {
    let s = parse(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [1 1 1]\nMediumInterface \"\" \"fog\"\n\
         Camera \"perspective\"\nWorldBegin\nMediumInterface \"fog\"\nShape \"sphere\"\nMediumInterface \"in\" \"\"\nLightSource \"point\"\nShape \"s\"",
    )
    .scene;
    assert_eq!(s.media.len(), 1);
    assert_eq!(s.media[0].entity.kind, "homogeneous");
    assert_eq!(s.camera.medium.as_deref(), Some("fog"));
    assert_eq!(s.shapes[0].inside_medium.as_deref(), Some("fog"));
    assert_eq!(s.shapes[0].outside_medium.as_deref(), Some("fog"));
    assert_eq!(s.shapes[1].inside_medium.as_deref(), Some("in"));
    assert_eq!(s.shapes[1].outside_medium, None);
    assert_eq!(s.lights[0].medium, None);
    assert_err("MakeNamedMedium \"m\" \"rgb sigma_a\" [1 1 1]", 1, 1, "string type");
}

#[test]
fn world_fragment_parses_standalone() {
    let out =
        parse("Translate 1 0 0\nShape \"trianglemesh\" \"integer indices\" [0 1 2] \"point P\" [0 0 0 1 0 0 0 1 0]");
    assert_eq!(out.scene.shapes.len(), 1);
    assert!(close(out.scene.shapes[0].render_from_object.start.apply_point([0.0; 3]), [1.0, 0.0, 0.0]));
    assert!(out.warnings.iter().any(|w| w.message.contains("fragment")));
}

#[test]
fn tokenizer_edge_cases_through_the_parser() {
    let s = parse(&world(
        "Shape \"s\" # comment \"string x\" \"ignored\"\n\"string name\" \"a \\\"quoted\\\" \\\\ name\\n\"\n\
         \"float v\"[-5e-51 .5 +1 1. 1e+3]#trailing",
    ))
    .scene;
    let ps = &s.shapes[0].entity.params;
    assert_eq!(ps.get_one_string("name", ""), "a \"quoted\" \\ name\n");
    assert_eq!(ps.get_floats("v"), Some(&[-0.0, 0.5, 1.0, 1.0, 1000.0][..]));
    assert!(ps.find("x").is_none());
}

#[test]
fn include_resolves_against_the_top_level_directory() {
    let d = tmpdir("include");
    std::fs::create_dir_all(d.join("sub")).unwrap();
    std::fs::write(d.join("main.pbrt"), "WorldBegin\nInclude \"sub/a.pbrt\"\nShape \"after\"\nWorldEnd\n").unwrap();
    // sub/a.pbrt includes "sub/b.pbrt": relative to main.pbrt's directory, not to sub/.
    std::fs::write(d.join("sub/a.pbrt"), "Translate 1 0 0\nInclude \"sub/b.pbrt\"\n").unwrap();
    std::fs::write(d.join("sub/b.pbrt"), "Shape \"sphere\" \"float radus\" 2\n").unwrap();
    let out = parse_file(&d.join("main.pbrt")).unwrap();
    let s = &out.scene;
    assert_eq!(s.shapes.len(), 2);
    // Include shares the graphics state: the Translate from a.pbrt applies after it.
    assert!(close(s.shapes[1].render_from_object.start.apply_point([0.0; 3]), [1.0, 0.0, 0.0]));
    assert_eq!(s.files_read.len(), 3);
    let unused = s.shapes[0].entity.params.report_unused("shape");
    let d0 = unused[0].clone().with_source();
    assert!(d0.loc.as_ref().unwrap().file.ends_with("b.pbrt"));
    assert_eq!(d0.source_line.as_deref(), Some("Shape \"sphere\" \"float radus\" 2"));
    // Parsed through tiny windows, the result is the same.
    let small = parse_file_with_window(&d.join("main.pbrt"), 7).unwrap();
    assert_eq!(small.scene, out.scene);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn include_cycle_and_missing_file() {
    let d = tmpdir("cycle");
    std::fs::write(d.join("a.pbrt"), "WorldBegin\nInclude \"b.pbrt\"\n").unwrap();
    std::fs::write(d.join("b.pbrt"), "\n  Include \"a.pbrt\"\n").unwrap();
    let e = parse_file(&d.join("a.pbrt")).unwrap_err();
    assert!(e.message.contains("Include cycle") && e.message.contains("a.pbrt -> "), "{e}");
    let loc = e.loc.unwrap();
    assert!(loc.file.ends_with("b.pbrt") && loc.line == 2 && loc.column == 11);
    let e = parse_str("Include \"does/not/exist.pbrt\"", "m.pbrt", Some(&d)).unwrap_err();
    assert!(e.message.contains("does/not/exist.pbrt"), "{e}");
    assert_eq!(e.loc.unwrap().column, 9);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn self_include_depth_is_bounded_without_canonical_cycles() {
    // A chain of distinct files deeper than the limit.
    let d = tmpdir("deep");
    for i in 0..MAX_INCLUDE_DEPTH + 2 {
        std::fs::write(d.join(format!("f{i}.pbrt")), format!("Include \"f{}.pbrt\"\n", i + 1)).unwrap();
    }
    let e = parse_file(&d.join("f0.pbrt")).unwrap_err();
    assert!(e.message.contains("nested more than"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn spectrum_from_spd_file() {
    let d = tmpdir("spd");
    std::fs::write(d.join("au.spd"), "# gold\n400 1.5 # first\n500 1.0\n\n600 0.5\n").unwrap();
    let s = parse_str(&world("Material \"metal\" \"spectrum eta\" \"au.spd\""), "m.pbrt", Some(&d)).unwrap().scene;
    assert_eq!(
        s.materials[0].entity.params.get_spectrum("eta"),
        Some(&SpectrumValue::Sampled(vec![400.0, 1.5, 500.0, 1.0, 600.0, 0.5]))
    );
    assert!(s.files_read.iter().any(|p| p.ends_with("au.spd")));
    let e = parse_str(&world("Material \"metal\" \"spectrum eta\" \"missing.spd\""), "m.pbrt", Some(&d)).unwrap_err();
    assert!(e.message.contains("missing.spd"), "{e}");
    std::fs::write(d.join("odd.spd"), "400 1 500").unwrap();
    assert!(parse_str(&world("Material \"metal\" \"spectrum eta\" \"odd.spd\""), "m.pbrt", Some(&d)).is_err());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn diagnostic_rendering_windows_long_lines() {
    let long = format!("WorldBegin Shape \"s\" \"float x\" [{} z]", "1 ".repeat(500));
    let e = parse_err(&long);
    let text = e.to_string();
    let snippet = text.lines().nth(3).unwrap();
    let caret = text.lines().nth(4).unwrap();
    assert!(snippet.len() < 200, "{text}");
    // The caret sits under the offending token.
    let col = caret.find('^').unwrap();
    assert_eq!(&snippet[col..col + 1], "z", "{text}");
}

#[test]
fn source_line_reads_files() {
    let d = tmpdir("srcline");
    let p = d.join("s.pbrt");
    std::fs::write(&p, "a\r\nsecond line\n").unwrap();
    let loc = FileLoc::new(p.display().to_string().into(), 2, 3);
    assert_eq!(source_line(&loc).as_deref(), Some("second line"));
    let loc1 = FileLoc::new(p.display().to_string().into(), 1, 1);
    assert_eq!(source_line(&loc1).as_deref(), Some("a"));
    assert_eq!(source_line(&FileLoc::new(p.display().to_string().into(), 9, 1)), None);
    assert_eq!(source_line(&FileLoc::builtin()), None);
    std::fs::remove_dir_all(&d).ok();
    let _ = Path::new("");
}

#[test]
fn bad_inputs_never_panic() {
    for text in [
        "",
        "[",
        "]",
        "\"",
        "\"\\",
        "#",
        "WorldBegin [",
        "Shape",
        "WorldBegin Shape \"s\" \"float",
        "WorldBegin Shape \"s\" \"float x\" [",
        "LookAt 1",
        "Texture \"a\"",
        "MediumInterface",
        "WorldBegin AttributeEnd AttributeEnd TransformEnd ObjectEnd WorldEnd",
        "\u{feff}WorldBegin",
        "\0",
        "WorldBegin Shape \"s\" \"texture t\" []",
        "WorldBegin Shape \"s\" \"spectrum t\" []",
    ] {
        let _ = parse_str(text, "x.pbrt", None);
    }
}

/// Diagnostics quote the text they were parsed from, even while other threads parse other
/// text under the same name (tests run in parallel; the quoted line once came from a global
/// table keyed by name, and a concurrent parse could replace it).
#[test]
fn concurrent_parses_of_one_name_quote_their_own_text() {
    std::thread::scope(|s| {
        for t in 0..4 {
            s.spawn(move || {
                for i in 0..300 {
                    let pad = "#\n".repeat((t + i) % 3);
                    let text =
                        format!("{pad}WorldBegin\nMakeNamedMaterial \"m{t}_{i}\" \"float roughness\" 1\nWorldEnd\n");
                    let line = 2 + ((t + i) % 3) as u32;
                    assert_err(&text, line, 1, "string type");
                }
            });
        }
    });
}

/// `transform_world` moves the camera, shapes, instances, lights and textures together: a
/// point keeps its camera-space position, and the camera's two transforms stay inverses.
#[test]
fn transform_world_moves_everything_together() {
    let mut o = parse(
        "LookAt 0 1 -5  0 0 0  0 1 0 Camera \"perspective\" WorldBegin
         Translate 1 2 3 Shape \"sphere\" LightSource \"point\" Texture \"t\" \"float\" \"checkerboard\"
         ObjectBegin \"o\" Shape \"sphere\" ObjectEnd ObjectInstance \"o\" WorldEnd",
    )
    .scene;
    let t = Transform::translate([1e3, -2.0, 7.0]).compose(&Transform::rotate(37.0, [1.0, 2.0, 3.0]).unwrap());
    let before = o.clone();
    o.transform_world(&t);
    let p = [0.5, -0.25, 2.0];
    let in_camera = |d: &SceneDescription, w: [f64; 3]| d.camera.camera_from_world.start.apply_point(w);
    let object_in_camera =
        |d: &SceneDescription, f: &dyn Fn(&SceneDescription) -> Transform| in_camera(d, f(d).apply_point(p));
    let getters: [&dyn Fn(&SceneDescription) -> Transform; 4] = [
        &|d| d.shapes[0].render_from_object.start,
        &|d| d.lights[0].render_from_light.start,
        &|d| d.textures[0].render_from_texture.start,
        &|d| d.instances[0].render_from_instance.start,
    ];
    for f in getters {
        let (a, b) = (object_in_camera(&before, f), object_in_camera(&o, f));
        assert!(close(a, b), "{a:?} vs {b:?}");
    }
    let c = &o.camera;
    let round_trip = c.camera_from_world.start.apply_point(c.world_from_camera.start.apply_point(p));
    assert!(close(round_trip, p), "{round_trip:?}");
    // The instance definition's shapes stay in instance space.
    assert_eq!(o.instance_definitions, before.instance_definitions);
}

/// `asset_files` lists every file-valued parameter once, resolved against the scene's
/// directory, in the description's order, without marking the parameters used.
#[test]
fn asset_files_are_every_file_valued_parameter_resolved() {
    let text = r#"Film "image" "string filename" "out.exr"
        WorldBegin
        LightSource "infinite" "string mapname" "sky.exr"
        Texture "t" "spectrum" "imagemap" "string filename" "tex/a.png"
        Shape "plymesh" "string filename" "mesh.ply"
        ObjectBegin "o"
        Shape "plymesh" "string filename" "/abs/inst.ply"
        ObjectEnd
        Shape "plymesh" "string filename" "mesh.ply"
        WorldEnd"#;
    let s = crate::parse_str(text, "t.pbrt", Some(std::path::Path::new("/scenes"))).unwrap().scene;
    let got = s.asset_files();
    let want: Vec<std::path::PathBuf> =
        ["/scenes/mesh.ply", "/abs/inst.ply", "/scenes/sky.exr", "/scenes/tex/a.png"].iter().map(Into::into).collect();
    assert_eq!(got, want);
    assert!(!s.shapes[0].entity.params.report_unused("shape").is_empty(), "reading them marks nothing used");
}

#[test]
fn a_missing_world_end_is_a_warning_and_a_fragment_is_not() {
    let out = parse("WorldBegin\nShape \"sphere\"\n");
    let w: Vec<_> = out.warnings.iter().filter(|w| w.message.contains("missing WorldEnd")).collect();
    assert_eq!(w.len(), 1, "{:?}", out.warnings);
    assert_eq!(w[0].loc.as_ref().map(|l| l.line), Some(3));
    assert_eq!(out.scene.shapes.len(), 1);
    assert!(!parse("WorldBegin\nWorldEnd\n").warnings.iter().any(|w| w.message.contains("WorldEnd")));
    // A world-block fragment (what an Include holds) warns that it is one, not about WorldEnd.
    let frag = parse("Shape \"sphere\"\n");
    assert!(!frag.warnings.iter().any(|w| w.message.contains("missing WorldEnd")), "{:?}", frag.warnings);
}
