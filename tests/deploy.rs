//! The batch-scheduler recipes in `deploy/`: every script parses (`bash -n`), every manifest is
//! a Kubernetes Job with the keys its role needs (checked by a small indentation-based reader
//! of the YAML subset the manifests use, and by PyYAML when python3 has it), and the recipes'
//! commands really work: the SLURM task scripts run without SLURM (SLURM_ARRAY_TASK_ID set by
//! hand) and the manifests' container commands run under `sh` with JOB_COMPLETION_INDEX set,
//! and their merged images equal the single render byte for byte.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &str, ext: &[&str]) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().and_then(|e| e.to_str()).is_some_and(|e| ext.contains(&e)))
        .collect();
    v.sort();
    v
}

#[test]
fn scripts_parse() {
    let scripts: Vec<PathBuf> =
        ["deploy/slurm", "deploy/k8s"].iter().flat_map(|d| files(d, &["sh", "sbatch"])).collect();
    assert!(scripts.len() >= 8, "{scripts:?}");
    for s in scripts {
        let out = Command::new("bash").arg("-n").arg(&s).output().unwrap();
        assert!(out.status.success(), "{}: {}", s.display(), String::from_utf8_lossy(&out.stderr));
    }
}

/// `path.to.key` → scalar value (lists: `path.key[i].sub`), for the block-style YAML the
/// manifests use: mappings by indentation, `- ` list items, `>-` folded scalars, flow lists
/// kept as text. Tabs and odd indentation are errors.
fn yaml_paths(text: &str) -> Result<BTreeMap<String, String>, String> {
    let mut out = BTreeMap::new();
    // (indent, path) of the open mappings; list counters per path.
    let mut stack: Vec<(usize, String)> = Vec::new();
    let mut counters: BTreeMap<String, usize> = BTreeMap::new();
    let mut folded: Option<(usize, String)> = None;
    for (n, raw) in text.lines().enumerate() {
        if raw.contains('\t') {
            return Err(format!("line {}: a tab", n + 1));
        }
        let line = raw.trim_end();
        let body = line.trim_start();
        let indent = line.len() - body.len();
        if let Some((fi, key)) = &folded {
            if body.is_empty() || indent > *fi {
                let v = out.entry(key.clone()).or_insert_with(String::new);
                if !v.is_empty() {
                    v.push(' ');
                }
                v.push_str(body);
                continue;
            }
            folded = None;
        }
        if body.is_empty() || body.starts_with('#') {
            continue;
        }
        if indent % 2 != 0 {
            return Err(format!("line {}: odd indentation", n + 1));
        }
        let (indent, body, item) = match body.strip_prefix("- ") {
            Some(rest) => (indent + 2, rest, true),
            None => (indent, body, false),
        };
        while stack.last().is_some_and(|(i, _)| *i >= indent) {
            stack.pop();
        }
        let mut parent = stack.last().map(|(_, p)| p.clone()).unwrap_or_default();
        if item {
            let c = counters.entry(parent.clone()).or_insert(0);
            parent = format!("{parent}[{c}]");
            *c += 1;
            stack.push((indent - 1, parent.clone()));
            if body == ">-" || body == "|" {
                folded = Some((indent - 2, parent.clone()));
                continue;
            }
            if !body.contains(": ") && !body.ends_with(':') {
                out.insert(parent.clone(), body.to_string());
                continue;
            }
        }
        let (key, value) = match body.split_once(": ") {
            Some((k, v)) => (k, v.trim()),
            None => (body.strip_suffix(':').ok_or_else(|| format!("line {}: not key: value", n + 1))?, ""),
        };
        let path = if parent.is_empty() { key.to_string() } else { format!("{parent}.{key}") };
        if value.is_empty() {
            stack.push((indent, path));
        } else if value == ">-" || value == "|" {
            folded = Some((indent, path));
        } else {
            out.insert(path, value.trim_matches('"').to_string());
        }
    }
    Ok(out)
}

#[test]
fn manifests_are_jobs_with_the_keys_they_need() {
    let manifests = files("deploy/k8s", &["yaml"]);
    assert_eq!(manifests.len(), 4, "{manifests:?}");
    for m in &manifests {
        let text = std::fs::read_to_string(m).unwrap();
        let k = yaml_paths(&text).unwrap_or_else(|e| panic!("{}: {e}", m.display()));
        let get = |p: &str| k.get(p).map(String::as_str).unwrap_or_else(|| panic!("{}: no {p} in {k:#?}", m.display()));
        assert_eq!(get("apiVersion"), "batch/v1");
        assert_eq!(get("kind"), "Job");
        assert_eq!(get("spec.template.spec.restartPolicy"), "Never");
        assert!(get("spec.template.spec.containers[0].image").contains("penumbra"));
        assert_eq!(get("spec.template.spec.volumes[0].persistentVolumeClaim.claimName"), "penumbra-data");
        assert_eq!(get("spec.template.spec.containers[0].volumeMounts[0].mountPath"), "/data");
        let command = get("spec.template.spec.containers[0].args[0]");
        let indexed = m.file_name().unwrap().to_str().unwrap().contains("items") || m.ends_with("frame-job.yaml");
        if indexed {
            assert_eq!(get("spec.completionMode"), "Indexed");
            assert!(get("spec.completions").parse::<u32>().unwrap() > 0);
            assert!(get("spec.parallelism").parse::<u32>().unwrap() > 0);
            assert!(command.contains("$JOB_COMPLETION_INDEX"), "{command}");
        }
        let sh = Command::new("sh").args(["-n", "-c", command]).output().unwrap();
        assert!(sh.status.success(), "{}: {command}: {}", m.display(), String::from_utf8_lossy(&sh.stderr));
    }
    // PyYAML, where python3 has it, reads the same structure.
    let check = "import sys, yaml\nfor f in sys.argv[1:]:\n    d = yaml.safe_load(open(f))\n    \
                 assert d['kind'] == 'Job' and d['spec']['template']['spec']['restartPolicy'] == 'Never', f\n    \
                 print(f, d['spec'].get('completionMode'), d['spec']['template']['spec']['containers'][0]['args'][0])";
    if let Ok(out) = Command::new("python3").arg("-c").arg("import yaml").output() {
        if out.status.success() {
            let out = Command::new("python3").arg("-c").arg(check).args(&manifests).output().unwrap();
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
            let text = String::from_utf8_lossy(&out.stdout);
            for m in &manifests {
                let k = yaml_paths(&std::fs::read_to_string(m).unwrap()).unwrap();
                let line = text.lines().find(|l| l.starts_with(m.to_str().unwrap())).unwrap();
                assert!(line.ends_with(&k["spec.template.spec.containers[0].args[0]"]), "{line}");
            }
        }
    }
}

const SCENE: &str = r#"
LookAt 0 3 6  0 0.5 0  0 1 0
Camera "perspective" "float fov" 40
Sampler "halton" "integer pixelsamples" 4
Film "image" "integer xresolution" 36 "integer yresolution" 28
WorldBegin
Material "matte"
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
Shape "sphere" "float radius" 0.7
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4]
  Translate 0 3 0
  Shape "trianglemesh" "integer indices" [0 2 1 0 3 2]
    "point P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1]
AttributeEnd
WorldEnd
"#;

fn temp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-deploy-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{cmd:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn single(dir: &Path, args: &[&str]) -> Vec<u8> {
    let out = dir.join("single.exr");
    run(Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("render")
        .arg(dir.join("scene.pbrt"))
        .args(args)
        .arg("-q")
        .arg("-o")
        .arg(&out));
    std::fs::read(out).unwrap()
}

/// frame.sbatch's tasks, then merge.sbatch, without SLURM: tiles (ratio) and samples
/// (directlighting, a progressive 3 × 2 spp render).
#[test]
fn slurm_frame_recipe_runs_and_merges_to_the_single_render() {
    for (split, integrator, parts, spp, single_spp) in
        [("tiles", "ratio", 5, "4", "4"), ("samples", "directlighting", 3, "2", "6")]
    {
        let dir = temp(split);
        std::fs::write(dir.join("scene.pbrt"), SCENE).unwrap();
        let out = dir.join("out");
        for i in 0..parts {
            run(Command::new("bash")
                .arg(root().join("deploy/slurm/frame.sbatch"))
                .env("SLURM_ARRAY_TASK_ID", i.to_string())
                .env("SCENE", dir.join("scene.pbrt"))
                .env("PARTS", parts.to_string())
                .env("OUT", &out)
                .env("SPLIT", split)
                .env("SPP", spp)
                .env("INTEGRATOR", integrator)
                .env("PENUMBRA", env!("CARGO_BIN_EXE_penumbra")));
        }
        let merge = |parts: u32| {
            Command::new("bash")
                .arg(root().join("deploy/slurm/merge.sbatch"))
                .env("OUT", &out)
                .env("PARTS", parts.to_string())
                .env("PENUMBRA", env!("CARGO_BIN_EXE_penumbra"))
                .output()
                .unwrap()
        };
        let m = merge(parts);
        assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
        assert_eq!(
            std::fs::read(out.join("frame.exr")).unwrap(),
            single(&dir, &["-i", integrator, "--spp", single_spp]),
            "{split}"
        );
        let m = merge(parts + 1);
        assert!(!m.status.success() && String::from_utf8_lossy(&m.stderr).contains(&format!("part-{parts}.shard")));
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// The Kubernetes manifests' container commands under `sh`, `/data` a temporary directory and
/// penumbra on PATH: the Indexed Job's pods (JOB_COMPLETION_INDEX 0 … 15), then the merge pod.
#[test]
fn k8s_frame_commands_run_and_merge_to_the_single_render() {
    let dir = temp("k8s");
    std::fs::write(dir.join("scene.pbrt"), SCENE).unwrap();
    let command = |file: &str| {
        let k = yaml_paths(&std::fs::read_to_string(root().join("deploy/k8s").join(file)).unwrap()).unwrap();
        let parts = k["spec.template.spec.containers[0].env[0].value"].clone();
        (k["spec.template.spec.containers[0].args[0]"].replace("/data", dir.to_str().unwrap()), parts, k)
    };
    let bin = Path::new(env!("CARGO_BIN_EXE_penumbra")).parent().unwrap().to_path_buf();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let (frame, parts, k) = command("frame-job.yaml");
    assert_eq!(k["spec.completions"], parts, "completions and PARTS agree");
    for i in 0..parts.parse::<u32>().unwrap() {
        run(Command::new("sh")
            .args(["-c", &frame])
            .env("JOB_COMPLETION_INDEX", i.to_string())
            .env("PARTS", &parts)
            .env("PATH", &path));
    }
    let (merge, merge_parts, _) = command("merge-job.yaml");
    assert_eq!(merge_parts, parts);
    run(Command::new("sh").args(["-c", &merge]).env("PARTS", &parts).env("PATH", &path));
    assert_eq!(std::fs::read(dir.join("out/frame.exr")).unwrap(), single(&dir, &[]));
    std::fs::remove_dir_all(&dir).ok();
}

/// sweep-item.sbatch for every item of the plan, then sweep-collect.sbatch: the rows of the
/// ordinary sweep (timings aside).
#[test]
fn slurm_sweep_recipe_collects_the_sweeps_rows() {
    let dir = temp("sweep");
    std::fs::write(dir.join("scene.pbrt"), SCENE).unwrap();
    let args = format!("{} -i directlighting,path --reference-spp 16 --budgets 1,4", dir.join("scene.pbrt").display());
    let exe = env!("CARGO_BIN_EXE_penumbra");
    let plan = Command::new(exe)
        .arg("sweep")
        .args(args.split(' '))
        .args(["-o", dir.join("fan").to_str().unwrap(), "--plan"])
        .output()
        .unwrap();
    assert!(plan.status.success(), "{}", String::from_utf8_lossy(&plan.stderr));
    let n: u32 = String::from_utf8_lossy(&plan.stdout).trim().parse().unwrap();
    assert_eq!(n, 5);
    let script = |name: &str, k: Option<u32>| {
        let mut c = Command::new("bash");
        c.arg(root().join("deploy/slurm").join(name))
            .env("SWEEP_ARGS", &args)
            .env("OUT", dir.join("fan"))
            .env("PENUMBRA", exe);
        if let Some(k) = k {
            c.env("SLURM_ARRAY_TASK_ID", k.to_string());
        }
        run(&mut c);
    };
    for k in 0..n {
        script("sweep-item.sbatch", Some(k));
    }
    script("sweep-collect.sbatch", None);
    run(Command::new(exe).arg("sweep").args(args.split(' ')).args(["-o", dir.join("plain").to_str().unwrap(), "-q"]));
    let untimed = |d: &str| -> Vec<String> {
        std::fs::read_to_string(dir.join(d).join("sweep.csv"))
            .unwrap()
            .lines()
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                [&f[..2], &f[5..]].concat().join(",")
            })
            .collect()
    };
    assert_eq!(untimed("fan"), untimed("plain"));
    assert_eq!(untimed("plain").len(), 5);
    std::fs::remove_dir_all(&dir).ok();
}

/// The SLURM recipes on a real one-node SLURM (`deploy/slurm/localhost-run.sh`: munged,
/// slurmctld and slurmd on localhost): two frames and a sweep submitted as job arrays with
/// dependent merge/collect jobs, compared with single renders byte for byte.
#[test]
#[ignore = "needs root and Debian's slurm-wlm (apt-get install slurm-wlm)"]
fn slurm_recipes_on_a_localhost_cluster() {
    let out = Command::new("bash")
        .arg(root().join("deploy/slurm/localhost-run.sh"))
        .env("PENUMBRA", env!("CARGO_BIN_EXE_penumbra"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    for what in ["frame: 7 SLURM tasks merged", "reference: 4 x 8 spp", "sweep: 4 rows collected"] {
        assert!(text.contains(what), "{text}");
    }
}
