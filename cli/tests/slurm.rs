//! A sharded bake on a real Slurm cluster: a private single-node cluster on this machine
//! (`scripts/slurm/cluster.sh`: munged, slurmctld and slurmd with their own configuration),
//! the documented submission (`scripts/slurm/submit.sh`: parameter plan, job array of 4 shards,
//! merge after them), compared with a one-machine bake artefact for artefact and pack for pack.
//! Needs Debian's slurm-wlm and munge and root (`scripts/test` installs them); fails, never
//! skips, without.

mod common;

use common::{asset, kage, scratch, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// A running private cluster, stopped when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Self {
        // Ports from the process id, so that concurrent runs on one machine do not meet.
        let port = (20000 + 2 * (std::process::id() % 10000)).to_string();
        let o = script("cluster.sh").args(["start", dir.to_str().unwrap(), &port]).output().expect("bash runs");
        let cluster = Self { dir: dir.to_path_buf(), conf: dir.join("slurm.conf") };
        assert!(
            o.status.success(),
            "the local Slurm cluster did not start (needs slurm-wlm and munge: bash scripts/test installs them):\n{}{}",
            stderr(&o),
            logs(dir)
        );
        cluster
    }

    /// A Slurm command against this cluster.
    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Waits until job `id` has left the queue; its final state.
    fn wait(&self, id: &str, limit: Duration) -> String {
        let start = Instant::now();
        loop {
            let q = self.command("squeue").args(["-h", "-j", id]).output().expect("squeue runs");
            if String::from_utf8_lossy(&q.stdout).trim().is_empty() || start.elapsed() > limit {
                break;
            }
            std::thread::sleep(Duration::from_millis(500));
        }
        let o = self.command("scontrol").args(["show", "job", id]).output().expect("scontrol runs");
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        text.split_whitespace().find_map(|w| w.strip_prefix("JobState=")).unwrap_or("UNKNOWN").to_string()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = script("cluster.sh").args(["stop", self.dir.to_str().unwrap()]).output();
    }
}

/// `bash scripts/slurm/NAME`.
fn script(name: &str) -> Command {
    let mut c = Command::new("bash");
    c.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/slurm").join(name));
    c
}

/// The cluster's logs, for a failure message.
fn logs(dir: &Path) -> String {
    let Ok(entries) = std::fs::read_dir(dir.join("log")) else { return String::new() };
    entries
        .flatten()
        .map(|e| format!("--- {}\n{}", e.path().display(), std::fs::read_to_string(e.path()).unwrap_or_default()))
        .collect()
}

/// Every job's output in `dir` (slurm-*.out), for a failure message.
fn outputs(dir: &Path) -> String {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().flatten().map(|e| e.path()).collect();
    files.retain(|p| p.extension().is_some_and(|e| e == "out"));
    files.sort();
    files.iter().map(|p| format!("--- {}\n{}", p.display(), std::fs::read_to_string(p).unwrap_or_default())).collect()
}

#[test]
fn a_sharded_bake_on_slurm_equals_a_one_machine_bake() {
    let d = scratch("slurm");
    for file in ["textured_light.gltf", "textured_light.bin", "stained_glass.png"] {
        std::fs::copy(asset(&format!("scenes/{file}")), d.join(file)).unwrap();
    }
    let scene = d.join("textured_light.gltf").to_str().unwrap().to_string();
    let env = asset("envmaps/sky.hdr");
    // Polygonal light and environment: BSPVT and PRT chunks, PRT's parameters chosen once by the
    // plan job from the error budget.
    // Receiver refinement on: every shard refines the same meshes (it is deterministic).
    let options = ["--env", &env, "--face-res", "16", "--refine-receivers", "2000"];
    // munged's socket path must stay short (108 bytes), whatever the checkout's path. Dropped
    // after the cluster (declared before it), so the daemons stop first.
    let short = tempfile::Builder::new().prefix("kage-slurm-").tempdir().unwrap();
    let cluster = Cluster::start(short.path());
    let db = d.join("farm").join("bake.redb");
    let o = script("submit.sh")
        .args([&scene, "4", db.to_str().unwrap()])
        .args(options)
        .env("SLURM_CONF", &cluster.conf)
        .env("KAGE", env!("CARGO_BIN_EXE_kage"))
        .output()
        .expect("bash runs");
    assert!(o.status.success(), "submit.sh: {}{}", stderr(&o), logs(&cluster.dir));
    let ids = String::from_utf8_lossy(&o.stdout).into_owned();
    let merge = ids.split_whitespace().last().expect("submit.sh prints the job ids").to_string();
    let state = cluster.wait(&merge, Duration::from_secs(900));
    let farm = d.join("farm");
    assert_eq!(state, "COMPLETED", "the merge job: {state}\n{ids}\n{}{}", outputs(&farm), logs(&cluster.dir));
    let shard_out = outputs(&farm);
    assert!((0..4).all(|i| shard_out.contains(&format!("shard {i}/4: baked"))), "{shard_out}");
    drop(cluster);

    // The same scene on one machine.
    let single = d.join("single.redb");
    let o = kage(&[&["bake", &scene, "--db", single.to_str().unwrap()], &options[..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let list = |db: &Path| {
        let o = kage(&["db", "list", "--db", db.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        String::from_utf8(o.stdout).unwrap()
    };
    let (merged, alone) = (list(&db), list(&single));
    assert!(merged.lines().count() > 8, "{merged}");
    assert!(merged == alone, "the merged database holds other artefacts:\n{merged}\nvs\n{alone}");
    // Nothing left to bake, and the same pack.
    let o = kage(&[&["bake", &scene, "--db", db.to_str().unwrap(), "--dry-run"], &options[..]].concat());
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("0 to bake"), "{out}");
    let pack = |db: &Path, name: &str| {
        let path = d.join(name);
        let o = kage(
            &[&["export", &scene, "--db", db.to_str().unwrap(), "-o", path.to_str().unwrap()], &options[..]].concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(path).unwrap()
    };
    assert!(pack(&db, "farm.glb") == pack(&single, "single.glb"), "packs differ");
    std::fs::remove_dir_all(d).unwrap();
}

/// A shard of a scene with an environment and no parameter plan says how to make one; a shard
/// needs its own database.
#[test]
fn a_shard_without_a_parameter_plan_says_how_to_make_one() {
    let d = scratch("shard-errors");
    let env = asset("envmaps/sky.hdr");
    let shard = d.join("shard.redb");
    let o = kage(&["bake", "--env", &env, "--shard", "0/2", "--db", shard.to_str().unwrap()]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("--dry-run") && e.contains("--base"), "{e}");
    let o = kage(&["bake", "--shard", "0/2"]);
    assert!(!o.status.success() && stderr(&o).contains("--db"), "{}", stderr(&o));
    let o = kage(&["bake", "--shard", "2/2", "--db", shard.to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("0 ≤ I < N"), "{}", stderr(&o));
    std::fs::remove_dir_all(d).unwrap();
}
