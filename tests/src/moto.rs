//! A real S3-compatible server for the object-store tests: `moto_server` (Python package
//! `moto[server]`, installed by `.ci/run`) on 127.0.0.1 at a free port, killed when the guard
//! drops. Missing moto is a failure naming the `pip install`, never a silent skip.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running `moto_server`; killed on drop.
pub struct MotoServer {
    child: Child,
    /// The port it listens on.
    pub port: u16,
    log_path: std::path::PathBuf,
}

/// The access key the servers accept (moto checks none unless started with auth).
pub const ACCESS_KEY: &str = "regolith-test";

fn free_port() -> std::io::Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

impl MotoServer {
    /// Starts a server that accepts any credentials.
    pub fn start() -> Result<MotoServer, String> {
        MotoServer::spawn(None)
    }

    /// Starts a server that checks credentials (moto's IAM mode) after `free_requests`
    /// unauthenticated ones (e.g. 1, to create a bucket): every request signed with keys moto
    /// does not know is then refused with 403.
    pub fn start_with_auth(free_requests: u32) -> Result<MotoServer, String> {
        MotoServer::spawn(Some(free_requests))
    }

    fn spawn(auth: Option<u32>) -> Result<MotoServer, String> {
        let port = free_port().map_err(|e| format!("no free port: {e}"))?;
        // moto logs every request: to a file, since an unread pipe would fill and stall it.
        let log_path = std::env::temp_dir().join(format!("regolith-moto-{port}.log"));
        let log = std::fs::File::create(&log_path)
            .map_err(|e| format!("creating {}: {e}", log_path.display()))?;
        let mut cmd = if which("moto_server") {
            Command::new("moto_server")
        } else {
            let mut c = Command::new("python3");
            c.args(["-m", "moto.server"]);
            c
        };
        cmd.args(["-H", "127.0.0.1", "-p", &port.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log);
        if let Some(n) = auth {
            cmd.env("INITIAL_NO_AUTH_ACTION_COUNT", n.to_string());
        }
        let child = cmd.spawn().map_err(|e| {
            format!("cannot start moto_server ({e}): install it with `pip install 'moto[server]'`")
        })?;
        let mut server = MotoServer {
            child,
            port,
            log_path,
        };
        let start = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            if let Ok(Some(status)) = server.child.try_wait() {
                let err = std::fs::read_to_string(&server.log_path).unwrap_or_default();
                return Err(format!(
                    "moto_server exited ({status}): {err}\ninstall it with `pip install 'moto[server]'`"
                ));
            }
            if start.elapsed() > Duration::from_secs(60) {
                return Err("moto_server did not listen within 60 s".to_string());
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        Ok(server)
    }

    /// The endpoint URL.
    pub fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.port)
    }

    /// The environment a regolith process needs to reach this server.
    pub fn env(&self) -> Vec<(&'static str, String)> {
        vec![
            ("AWS_ACCESS_KEY_ID", ACCESS_KEY.to_string()),
            ("AWS_SECRET_ACCESS_KEY", "regolith-test-secret".to_string()),
            ("AWS_ENDPOINT_URL", self.endpoint()),
            ("AWS_ALLOW_HTTP", "true".to_string()),
            ("AWS_REGION", "us-east-1".to_string()),
        ]
    }

    /// Sends a raw unsigned HTTP request and returns (status, body).
    fn http(&self, method: &str, path: &str) -> Result<(u16, String), String> {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).map_err(|e| e.to_string())?;
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
            self.port
        )
        .map_err(|e| e.to_string())?;
        let mut out = String::new();
        s.read_to_string(&mut out).map_err(|e| e.to_string())?;
        let status = out
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = out.split_once("\r\n\r\n").map(|(_, b)| b).unwrap_or("");
        Ok((status, body.to_string()))
    }

    /// Creates a bucket (object_store cannot): an unsigned `PUT /bucket`.
    pub fn create_bucket(&self, name: &str) -> Result<(), String> {
        match self.http("PUT", &format!("/{name}"))? {
            (200, _) => Ok(()),
            (s, body) => Err(format!("creating bucket {name}: HTTP {s}: {body}")),
        }
    }

    /// Stores `bytes` at `bucket/key` with an unsigned PUT (for planting strays).
    pub fn put_object(&self, bucket_key: &str, bytes: &[u8]) -> Result<(), String> {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).map_err(|e| e.to_string())?;
        write!(
            s,
            "PUT /{bucket_key} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            self.port,
            bytes.len()
        )
        .and_then(|()| s.write_all(bytes))
        .map_err(|e| e.to_string())?;
        let mut out = String::new();
        s.read_to_string(&mut out).map_err(|e| e.to_string())?;
        if out.starts_with("HTTP/1.1 200") {
            Ok(())
        } else {
            Err(format!("PUT {bucket_key}: {out}"))
        }
    }

    /// Every key stored in the server (all buckets), from moto's state dump (which needs no
    /// credentials, so it also works on a server checking them).
    pub fn all_keys(&self) -> Result<Vec<String>, String> {
        let (status, body) = self.http("GET", "/moto-api/data.json")?;
        if status != 200 {
            return Err(format!("moto-api: HTTP {status}"));
        }
        // The body may be chunked; the JSON is the part between the first `{` and last `}`.
        let json = body
            .find('{')
            .zip(body.rfind('}'))
            .and_then(|(a, b)| body.get(a..=b))
            .unwrap_or("{}");
        let v: serde_json::Value = serde_json::from_str(json).map_err(|e| e.to_string())?;
        let mut keys: Vec<String> = v["s3"]["FakeKey"]
            .as_array()
            .into_iter()
            .flatten()
            // Deleted keys stay in the dump, marked disposed.
            .filter(|k| k["disposed"] != serde_json::Value::Bool(true))
            .filter_map(|k| {
                Some(format!(
                    "{}/{}",
                    k["bucket_name"].as_str()?,
                    k["name"].as_str()?
                ))
            })
            .collect();
        keys.sort();
        Ok(keys)
    }
}

fn which(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

impl Drop for MotoServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log_path);
    }
}
