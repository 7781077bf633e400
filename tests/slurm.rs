//! `deploy/slurm/` on a real Slurm cluster: Debian's `slurm-wlm` with `munge`, one node (this
//! machine) running `slurmctld` and `slurmd`, started here from a `slurm.conf` written to a
//! temporary folder (no system file is read or written besides the programs) and stopped at
//! the end. `deploy/slurm/submit.sh` runs unmodified, as a user would run it, and the merged
//! image must equal a whole render bit for bit. Also under the real scheduler: a request the
//! cluster cannot satisfy is refused at once, a band cancelled mid-render leaves no part, the
//! merge then names it, rendering that band again gives the same image, a band from another
//! backend is refused, and `status.sh` says where each band is. A second cluster whose one
//! node declares more CPUs than this machine has (`SlurmdParameters=config_overrides`) runs
//! the same script with more CPUs per band.
//!
//! It needs root (the daemons run as root) and the programs `.ci/run` installs; without them
//! it records a skip (tests/common), which `.ci/run` counts as a failure.

mod common;

use common::{exr_bits as bits, seed_whole_bits as whole};

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

const PROGRAMS: [&str; 8] = ["munged", "slurmctld", "slurmd", "sbatch", "squeue", "sinfo", "scancel", "scontrol"];

/// Where `program` is on PATH or in the system folders Debian installs daemons to.
fn find(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs = std::env::split_paths(&path).chain(["/usr/sbin", "/sbin"].map(PathBuf::from));
    dirs.map(|d| d.join(program)).find(|p| p.is_file())
}

fn text(out: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// A one-node Slurm cluster of this machine, stopped when dropped.
struct Cluster {
    dir: tempfile::TempDir,
    conf: PathBuf,
    node: String,
    /// The CPUs the node declares.
    cpus: u32,
    /// The daemons' pid files, in the order they are stopped.
    pid_files: Vec<PathBuf>,
}

impl Cluster {
    /// Starts munged, slurmctld and slurmd. `declared_cpus`: the node's CPUs as the cluster
    /// knows them, where not this machine's own (`slurmd -C`).
    fn start(declared_cpus: Option<u32>) -> Cluster {
        let dir = tempfile::Builder::new().prefix("strahl-slurm").tempdir().unwrap();
        // munged wants the folders on the socket's path searchable by everyone.
        std::fs::set_permissions(dir.path(), std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
        let d = dir.path();
        for sub in ["munge", "state", "spool", "log"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        let key: Vec<u8> =
            (0..1024u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8 ^ std::process::id() as u8).collect();
        std::fs::write(d.join("munge/munge.key"), key).unwrap();
        std::fs::set_permissions(d.join("munge/munge.key"), std::os::unix::fs::PermissionsExt::from_mode(0o600))
            .unwrap();
        let socket = d.join("munge/socket");
        let mut cluster = Cluster {
            conf: d.join("slurm.conf"),
            node: String::new(),
            cpus: 0,
            pid_files: vec![d.join("slurmd.pid"), d.join("slurmctld.pid"), d.join("munge/munged.pid")],
            dir,
        };
        let d = cluster.dir.path();
        run_ok(Command::new(find("munged").unwrap()).args([
            "--force".into(),
            format!("--socket={}", socket.display()),
            format!("--key-file={}", d.join("munge/munge.key").display()),
            format!("--log-file={}", d.join("munge/munged.log").display()),
            format!("--pid-file={}", d.join("munge/munged.pid").display()),
            format!("--seed-file={}", d.join("munge/munged.seed").display()),
        ]));

        // The node as slurmd sees this machine: its name, CPUs, sockets, cores and memory.
        let probe = run_ok(Command::new(find("slurmd").unwrap()).arg("-C"));
        let line = String::from_utf8_lossy(&probe.stdout).lines().next().unwrap_or_default().to_string();
        let field =
            |name: &str| line.split_whitespace().find_map(|f| f.strip_prefix(&format!("{name}="))).map(str::to_string);
        cluster.node = field("NodeName").expect("slurmd -C names the node");
        let real_cpus: u32 = field("CPUs").and_then(|c| c.parse().ok()).expect("slurmd -C counts the CPUs");
        cluster.cpus = declared_cpus.unwrap_or(real_cpus);
        let node_line = match declared_cpus {
            // The machine as it is: slurmd -C's whole line.
            None => line.replace(
                &format!("NodeName={}", cluster.node),
                &format!("NodeName={} NodeAddr=127.0.0.1", cluster.node),
            ),
            Some(c) => format!("NodeName={} NodeAddr=127.0.0.1 CPUs={c}", cluster.node),
        };
        let [ctld_port, d_port] = free_ports();
        let conf = format!(
            "ClusterName=strahltest\n\
             SlurmctldHost={node}(127.0.0.1)\n\
             SlurmctldPort={ctld_port}\nSlurmdPort={d_port}\n\
             SlurmUser=root\nSlurmdUser=root\n\
             AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket={socket}\n\
             StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/log/slurmctld.log\nSlurmdLogFile={d}/log/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
             JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
             SchedulerType=sched/backfill\nSelectType=select/cons_tres\nSelectTypeParameters=CR_CPU\n\
             MpiDefault=none\nSwitchType=switch/none\nReturnToService=2\nKillWait=5\n{overrides}\
             {node_line} State=UNKNOWN\n\
             PartitionName=strahl Nodes={node} Default=YES MaxTime=INFINITE State=UP\n",
            node = cluster.node,
            socket = socket.display(),
            d = d.display(),
            overrides = if declared_cpus.is_some() { "SlurmdParameters=config_overrides\n" } else { "" },
        );
        std::fs::write(&cluster.conf, conf).unwrap();
        let f = cluster.conf.to_str().unwrap().to_string();
        run_ok(Command::new(find("slurmctld").unwrap()).args(["-f", &f]));
        run_ok(Command::new(find("slurmd").unwrap()).args(["-f", &f, "-N", &cluster.node]));
        cluster.wait_until("the node to be idle", Duration::from_secs(60), |c| {
            let out = c.cmd("sinfo").args(["-h", "-o", "%T"]).output().unwrap();
            String::from_utf8_lossy(&out.stdout).trim() == "idle"
        });
        cluster
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    /// `program` with this cluster's configuration, the built `strahl` first on PATH, from the
    /// repository root and without a backend from the caller's environment.
    fn cmd(&self, program: &str) -> Command {
        let bin = Path::new(env!("CARGO_BIN_EXE_strahl")).parent().unwrap().to_path_buf();
        let rest = std::env::var_os("PATH").unwrap_or_default();
        let path = std::env::join_paths([bin].into_iter().chain(std::env::split_paths(&rest))).unwrap();
        let program = find(program).unwrap_or_else(|| PathBuf::from(program));
        let mut c = Command::new(program);
        c.current_dir(root()).env("SLURM_CONF", &self.conf).env("PATH", path).env_remove("STRAHL_BACKEND");
        for (k, _) in std::env::vars_os() {
            if k.to_string_lossy().starts_with("SBATCH_") || k.to_string_lossy().starts_with("SLURM_") {
                c.env_remove(k);
            }
        }
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Runs `deploy/slurm/submit.sh ARGS` and returns its output.
    fn submit(&self, args: &[&str]) -> Output {
        self.cmd("bash").arg("deploy/slurm/submit.sh").args(args).output().unwrap()
    }

    fn wait_until(&self, what: &str, limit: Duration, mut done: impl FnMut(&Cluster) -> bool) {
        let start = Instant::now();
        while !done(self) {
            assert!(start.elapsed() < limit, "waited {limit:?} for {what}; {}", self.logs());
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The queue's lines `JOBID STATE REASON`, every array task on its own line.
    fn queue(&self) -> String {
        let out = self.cmd("squeue").args(["-h", "-r", "-o", "%i %T %r"]).output().unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Waits until no job is queued or running.
    fn wait_idle_queue(&self) {
        self.wait_until("every job to end", Duration::from_secs(240), |c| c.queue().trim().is_empty());
    }

    fn logs(&self) -> String {
        let read = |p: &str| std::fs::read_to_string(self.path().join(p)).unwrap_or_default();
        let tail =
            |s: String| s.lines().rev().take(15).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n");
        format!(
            "queue:\n{}\nslurmctld.log:\n{}\nslurmd.log:\n{}",
            self.queue(),
            tail(read("log/slurmctld.log")),
            tail(read("log/slurmd.log"))
        )
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = self.cmd("scancel").args(["--user=root"]).output();
        for pid_file in &self.pid_files {
            let Some(pid) = std::fs::read_to_string(pid_file).ok().and_then(|p| p.trim().parse::<u32>().ok()) else {
                continue;
            };
            let _ = Command::new("kill").arg(pid.to_string()).status();
            let start = Instant::now();
            while Path::new(&format!("/proc/{pid}")).exists() && start.elapsed() < Duration::from_secs(20) {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
}

fn run_ok(c: &mut Command) -> Output {
    let out = c.output().unwrap_or_else(|e| panic!("{c:?}: {e}"));
    assert!(out.status.success(), "{c:?} failed:\n{}", text(&out));
    out
}

/// Two TCP ports free on this machine now.
fn free_ports() -> [u16; 2] {
    let a = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let b = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    [a.local_addr().unwrap().port(), b.local_addr().unwrap().port()]
}

/// The job id `submit.sh` printed for the array ("... as job array ID ...").
fn array_id(submitted: &Output) -> String {
    let out = String::from_utf8_lossy(&submitted.stdout);
    out.split("job array ").nth(1).and_then(|s| s.split_whitespace().next()).unwrap_or_else(|| panic!("{out}")).into()
}

fn status(cluster: &Cluster, out: &Path) -> (bool, String) {
    let o = cluster.cmd("bash").args(["deploy/slurm/status.sh", out.to_str().unwrap()]).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stdout).into_owned())
}

/// Path traced on the CPU: every pixel draws from its own random streams, and a band takes
/// seconds at one CPU (16.6 M samples), long enough to be cancelled while it renders.
const FLAGS: [&str; 10] = ["--backend", "cpu", "--mode", "path", "--spp", "384", "--width", "480", "--height", "360"];

#[test]
fn submit_sh_runs_on_a_real_slurm_cluster_and_survives_a_cancelled_band() {
    let root_user =
        Command::new("id").arg("-u").output().is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    let missing: Vec<&str> = PROGRAMS.into_iter().filter(|p| find(p).is_none()).collect();
    if !root_user || !missing.is_empty() {
        common::skip(&format!(
            "a real Slurm cluster needs root and Debian's slurm-wlm and munge (.ci/run installs them); root: {root_user}, missing: {missing:?}"
        ));
        return;
    }
    let cluster = Cluster::start(None);
    let sinfo = run_ok(&mut cluster.cmd("sinfo"));
    println!("$ sinfo\n{}", String::from_utf8_lossy(&sinfo.stdout));

    // More CPUs per band than any node has: refused at once, naming the resource; nothing queued.
    let too_many = (cluster.cpus + 1).to_string();
    let out_dir = cluster.path().join("seed render");
    let o = cluster.submit(&["-c", &too_many, "assets/scenes/seed.toml", out_dir.to_str().unwrap(), "4"]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("$ deploy/slurm/submit.sh -c {too_many} assets/scenes/seed.toml OUT 4\n{err}");
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        err.contains(&format!("{too_many} CPUs")) && err.contains(&format!("the most a node has is {}", cluster.cpus)),
        "{err}"
    );
    assert_eq!(cluster.queue().trim(), "", "nothing submitted");

    // Four bands (a space in the output folder: the merge job's command must quote it).
    let out = out_dir.to_str().unwrap();
    let mut args = vec!["assets/scenes/seed.toml", out, "4"];
    args.extend(FLAGS);
    let o = cluster.submit(&args);
    assert!(o.status.success(), "{}", text(&o));
    println!("$ deploy/slurm/submit.sh {}\n{}", args.join(" "), String::from_utf8_lossy(&o.stdout));
    let array = array_id(&o);
    // Band 1 is cancelled once it renders.
    let band1 = format!("{array}_1");
    cluster.wait_until("band 1 to run", Duration::from_secs(120), |c| c.queue().contains(&format!("{band1} RUNNING")));
    println!("$ squeue\n{}", String::from_utf8_lossy(&run_ok(cluster.cmd("squeue").arg("-r")).stdout));
    let (done, said) = status(&cluster, &out_dir);
    println!("$ deploy/slurm/status.sh OUT\n{said}");
    assert!(!done && said.contains("band 1 of 4: running"), "{said}");
    std::thread::sleep(Duration::from_millis(300));
    run_ok(cluster.cmd("scancel").arg(&band1));
    cluster.wait_idle_queue();
    let log1 = std::fs::read_to_string(out_dir.join("tile-1.log")).unwrap();
    assert!(log1.contains("CANCELLED") && !log1.contains("wrote"), "band 1 was cancelled while it rendered: {log1}");

    let entries: Vec<String> =
        std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(!entries.iter().any(|e| e.contains("part-1")), "a cancelled band leaves no part: {entries:?}");
    for k in [0, 2, 3] {
        assert!(entries.contains(&format!("part-{k}.exr")), "band {k}: {entries:?}");
    }
    let merge_log = std::fs::read_to_string(out_dir.join("merge.log")).unwrap();
    assert!(merge_log.contains("band 1 of 4 missing") && merge_log.contains("--tile 1/4"), "{merge_log}");
    assert!(!out_dir.join("image.exr").exists(), "no image from three bands");
    let (done, said) = status(&cluster, &out_dir);
    println!("$ deploy/slurm/status.sh OUT\n{said}");
    assert!(!done, "{said}");
    assert!(said.contains("band 0 of 4: done") && said.contains("band 1 of 4: missing"), "{said}");
    assert!(said.contains("--bands 1 assets/scenes/seed.toml"), "status gives the command again: {said}");

    // The band again, as status.sh says: the same image as a whole render, bit for bit.
    let mut again = vec!["--bands", "1"];
    again.extend(&args);
    let o = cluster.submit(&again);
    assert!(o.status.success(), "{}", text(&o));
    cluster.wait_idle_queue();
    let (done, said) = status(&cluster, &out_dir);
    println!("$ deploy/slurm/submit.sh --bands 1 ...\n$ deploy/slurm/status.sh OUT\n{said}");
    assert!(done && said.contains("merge: done"), "{said}\n{}", cluster.logs());
    let png = image::open(out_dir.join("image.png")).expect("the merge job writes image.png").to_rgb8();
    assert_eq!(png.dimensions(), (480, 360));
    assert!(
        bits(&out_dir.join("image.exr")) == whole(cluster.path(), &FLAGS),
        "the merged bands differ from the whole render"
    );

    drop(cluster);

    // A node with more CPUs than this machine's (declared so): bands of several CPUs each, from
    // the same script.
    let wide = Cluster::start(Some(8));
    let out_dir = wide.path().join("wide");
    let small = ["--backend", "cpu", "--mode", "path", "--spp", "4", "--width", "96", "--height", "61"];
    let mut args = vec!["-c", "4", "assets/scenes/seed.toml", out_dir.to_str().unwrap(), "3"];
    args.extend(small);
    let o = wide.submit(&args);
    assert!(o.status.success(), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("(4 CPU(s) each)"), "{}", text(&o));
    wide.wait_idle_queue();
    let log = std::fs::read_to_string(out_dir.join("tile-0.log")).unwrap();
    assert!(log.contains("with 4 CPU(s)"), "{log}");
    assert!(
        bits(&out_dir.join("image.exr")) == whole(wide.path(), &small),
        "the merged bands differ from the whole render"
    );

    // A band rendered on another backend (a node whose STRAHL_BACKEND differs): the merge
    // refuses the parts and names the backends.
    std::fs::remove_file(out_dir.join("part-2.exr")).unwrap();
    std::fs::remove_file(out_dir.join("image.exr")).unwrap();
    let mut on_gpu = vec!["--bands", "2"];
    on_gpu.extend(&args);
    let backend_at = on_gpu.iter().position(|a| *a == "cpu").unwrap();
    on_gpu[backend_at] = "gpu";
    let o = wide.submit(&on_gpu);
    assert!(o.status.success(), "{}", text(&o));
    wide.wait_idle_queue();
    let merge_log = std::fs::read_to_string(out_dir.join("merge.log")).unwrap();
    assert!(merge_log.contains("come from different renders: backend cpu against gpu"), "{merge_log}");
    assert!(!out_dir.join("image.exr").exists());
}
