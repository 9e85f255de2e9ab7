//! Validation fanned out on a real Ray cluster against a database on an S3-compatible server:
//! `moto_server` on 127.0.0.1 holds the database (`s3://…`), a head and two worker nodes are
//! started on this machine (`ray start`, each node a separate raylet),
//! `tools/distributed/ray_validate.py` submits the shards as Ray tasks, and one worker node is
//! killed (its whole process group, SIGKILL) while the shards run. The run must complete (Ray
//! retries the lost task on the other node; the retried shard skips what was stored) and the
//! certificates must be the ones one `validate` process writes on the same campaign compiled
//! into a folder (which has the same release id).
//!
//! Needs the Python packages `ray` and `moto[server]` (`.ci/run` installs them); without them
//! the test fails saying so.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::HashMap;
use std::net::TcpListener;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{assert_matches_doc_schema, certificate_ids, generate_mini, regolith};
use regolith_tests::moto::MotoServer;
use serde_json::Value;

/// The Python that has `ray`: `$REGOLITH_PYTHON` or `python3`.
fn python() -> String {
    std::env::var("REGOLITH_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// The `ray` command next to that Python's scripts.
fn ray_cli() -> PathBuf {
    let out = Command::new(python())
        .args([
            "-c",
            "import ray, shutil, sys, os; print(shutil.which('ray') or os.path.join(os.path.dirname(sys.executable), 'ray'))",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "the Python package `ray` is needed for this test: python3 -m pip install 'ray[default]==2.60.0' ({})",
        String::from_utf8_lossy(&out.stderr).trim()
    );
    PathBuf::from(String::from_utf8(out.stdout).unwrap().trim())
}

/// A TCP port free right now on 127.0.0.1.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// `n` consecutive free ports (for a node's worker processes).
fn free_range(n: u16) -> u16 {
    for base in (20000u16..60000).step_by(97) {
        let held: Vec<TcpListener> = (base..base + n)
            .map_while(|p| TcpListener::bind(("127.0.0.1", p)).ok())
            .collect();
        if held.len() == n as usize {
            return base;
        }
    }
    panic!("no {n} consecutive free ports");
}

/// A Ray node (`ray start --block` in its own process group), killed with its processes on drop.
struct Node(Option<Child>);

impl Node {
    fn start(ray: &Path, args: &[String], env: &[(&str, String)], log: &Path) -> Node {
        let log = std::fs::File::create(log).unwrap();
        let child = Command::new(ray)
            .arg("start")
            .args(args)
            .args(["--block", "--disable-usage-stats"])
            .env("RAY_USAGE_STATS_ENABLED", "0")
            .envs(env.iter().map(|(k, v)| (k, v)))
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .process_group(0)
            .spawn()
            .unwrap();
        Node(Some(child))
    }

    /// The pid of `ray start`, the root of the node's processes.
    fn pid(&self) -> Option<u32> {
        self.0.as_ref().map(Child::id)
    }

    /// SIGKILL to everything of the node, as when its machine dies: its process group
    /// (raylet, object store) and every process descending from it — Ray puts each worker in
    /// a process group of its own, and a task's `regolith` is that worker's child.
    fn kill(&mut self) {
        if let Some(mut child) = self.0.take() {
            let root = child.id();
            let all = processes();
            let parents = parent_map(&all);
            let tree: Vec<u32> = all
                .iter()
                .filter(|p| descends_from(&parents, p.pid, root))
                .map(|p| p.pid)
                .collect();
            let _ = Command::new("kill")
                .args(["-KILL", "--", &format!("-{root}")])
                .args(tree.iter().map(u32::to_string))
                .stderr(Stdio::null())
                .status();
            // Should the kill fail, still never wait on a live process.
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// One process of this machine: pid, parent, command line.
struct Process {
    pid: u32,
    ppid: u32,
    cmdline: String,
}

/// Every process, from /proc.
fn processes() -> Vec<Process> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    dir.filter_map(|e| {
        let pid: u32 = e.ok()?.file_name().to_str()?.parse().ok()?;
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
        // `pid (comm) state ppid …`: the command may hold spaces and parentheses.
        let ppid = stat
            .rsplit_once(')')?
            .1
            .split_whitespace()
            .nth(1)?
            .parse()
            .ok()?;
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).ok()?;
        let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
        Some(Process { pid, ppid, cmdline })
    })
    .collect()
}

/// Each process's parent.
fn parent_map(all: &[Process]) -> HashMap<u32, u32> {
    all.iter().map(|p| (p.pid, p.ppid)).collect()
}

/// Whether `pid` is `root` or one of its descendants.
fn descends_from(parents: &HashMap<u32, u32>, pid: u32, root: u32) -> bool {
    let mut p = pid;
    for _ in 0..64 {
        if p == root {
            return true;
        }
        match parents.get(&p) {
            Some(&q) if q != p && q != 0 => p = q,
            _ => return false,
        }
    }
    false
}

/// The node (index into `nodes`) on which a `regolith … --shard` task process runs, if any.
fn node_running_a_shard(nodes: &[Node]) -> Option<usize> {
    let all = processes();
    let parents = parent_map(&all);
    let shards: Vec<u32> = all
        .iter()
        .filter(|p| p.cmdline.contains(" validate ") && p.cmdline.contains("--shard"))
        .map(|p| p.pid)
        .collect();
    nodes.iter().position(|n| {
        n.pid()
            .is_some_and(|root| shards.iter().any(|&s| descends_from(&parents, s, root)))
    })
}

impl Drop for Node {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Waits until `ray status` lists `n` alive nodes.
fn wait_for_nodes(ray: &Path, address: &str, n: usize, logs: &Path) {
    let t0 = Instant::now();
    loop {
        let out = Command::new(ray)
            .args(["status", "--address", address])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let alive = text
            .split("Pending:")
            .next()
            .unwrap_or("")
            .lines()
            .filter(|l| l.trim_start().starts_with("1 node_"))
            .count();
        if alive >= n {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(180),
            "the Ray cluster did not reach {n} nodes in 3 min; logs in {}:\n{text}",
            logs.display()
        );
        std::thread::sleep(Duration::from_secs(2));
    }
}

#[test]
fn ray_runs_the_shards_through_a_killed_worker_to_the_same_certificates() {
    let ray = ray_cli();
    let s3 = MotoServer::start().unwrap_or_else(|e| panic!("{e}"));
    s3.create_bucket("lab").unwrap();
    let env = s3.env();
    let on_s3 = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_regolith"))
            .args(args)
            .envs(env.iter().map(|(k, v)| (k, v)))
            .output()
            .unwrap()
    };
    let db = "s3://lab/terrain";
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    let one = dir.path().join("one");
    generate_mini(&camp, 7);
    for target in [one.to_str().unwrap(), db] {
        let out = on_s3(&[
            "compile",
            camp.to_str().unwrap(),
            "--db",
            target,
            "--release",
            "ray@1.0.0",
        ]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let entries = ["--entry", "laser/0.01", "--entry", "laser/0.02"];
    let mut args = vec!["--json", "validate", one.to_str().unwrap()];
    args.extend(entries);
    let out = regolith(&args);
    let whole: Value = serde_json::from_slice(&out.stdout).unwrap();

    // Ray's session folder holds unix sockets: keep its path short.
    let ray_tmp = tempfile::Builder::new()
        .prefix("rg")
        .tempdir_in("/tmp")
        .unwrap();
    let logs = dir.path();
    let port = free_port();
    let address = format!("127.0.0.1:{port}");
    let s = |x: &str| x.to_string();
    let _head = Node::start(
        &ray,
        &[
            s("--head"),
            format!("--port={port}"),
            s("--num-cpus=0"),
            s("--include-dashboard=false"),
            s("--object-store-memory=80000000"),
            format!("--temp-dir={}", ray_tmp.path().display()),
        ],
        &env,
        &logs.join("head.log"),
    );
    wait_for_nodes(&ray, &address, 1, logs);
    let mut workers = Vec::new();
    for w in 0..2 {
        let base = free_range(60);
        workers.push(Node::start(
            &ray,
            &[
                format!("--address={address}"),
                s("--num-cpus=1"),
                s("--object-store-memory=80000000"),
                format!("--node-manager-port={}", free_port()),
                format!("--object-manager-port={}", free_port()),
                format!("--metrics-export-port={}", free_port()),
                format!("--dashboard-agent-listen-port={}", free_port()),
                format!("--dashboard-agent-grpc-port={}", free_port()),
                format!("--runtime-env-agent-port={}", free_port()),
                format!("--min-worker-port={}", base),
                format!("--max-worker-port={}", base + 59),
            ],
            &env,
            &logs.join(format!("worker{w}.log")),
        ));
        // One at a time: two raylets starting at once race for the same default ports.
        wait_for_nodes(&ray, &address, 2 + w, logs);
    }

    let driver = crate_root().join("../tools/distributed/ray_validate.py");
    let mut cmd = Command::new(python());
    cmd.arg(&driver)
        .args(["--address", &address])
        .args(["--regolith", env!("CARGO_BIN_EXE_regolith")])
        .args(["--db", db, "--shards", "2"])
        .args(entries)
        .envs(env.iter().map(|(k, v)| (k, v)))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let run = cmd.spawn().unwrap();
    // Kill the node running a shard one second into it (a shard of 4 units takes 4–9 s here):
    // the task is lost mid-way, as when a machine dies.
    let t0 = Instant::now();
    let victim = loop {
        if let Some(k) = node_running_a_shard(&workers) {
            break k;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "no shard started in 5 min"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    std::thread::sleep(Duration::from_secs(1));
    workers[victim].kill();
    let out = run.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "driver failed:\n{err}"
    );
    assert!(err.contains("2/2 shards"), "{err}");
    // Ray saw the node die under a running shard and ran that shard again.
    assert!(
        err.contains("will be retried"),
        "no task was lost with the killed node:\n{err}"
    );
    eprintln!("{err}");
    let merged: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not the merge's JSON ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    assert_matches_doc_schema("validate", &merged);
    assert_eq!(merged["release_id"], whole["release_id"]);
    assert_eq!(
        certificate_ids(&merged),
        certificate_ids(&whole),
        "Ray's certificates differ from one process's"
    );
    let out = on_s3(&["verify", db]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

fn crate_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
