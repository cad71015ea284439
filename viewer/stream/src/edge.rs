//! A CDN in miniature on loopback, for the tests and `snerf bench publish`: the Debian
//! `caddy` as the origin and TLS front, `varnish` as the caching edge between them
//! (PUBLISH.md, "Testing behind a real edge"). Unprivileged processes on free loopback
//! ports, with their configuration and state in a folder of the caller's; stopped on drop.
//!
//! ```text
//! client --https (h1/h2/h3)--> caddy front :tls ----http----> varnish edge :edge
//!                                       (plain http clients may use :edge directly)
//! varnish --http--> caddy origin :origin (file_server of the published folder, cache
//!                   headers + CORS as PUBLISH.md documents)
//! ```
//!
//! Varnish speaks plain HTTP only, so TLS ends in front of it, as it does at a CDN's edge
//! (the TLS terminator and the cache are one box there). The cache key is the path and
//! query alone, so the TLS front and direct clients share entries.

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

/// What the edge enforces.
#[derive(Clone, Debug, Default)]
pub struct EdgeOptions {
    /// A private scene: varnish answers 401 (nothing of the scene) unless the request
    /// carries `Authorization: Bearer TOKEN`.
    pub bearer: Option<String>,
}

pub struct Edge {
    pub dir: PathBuf,
    caddy: Child,
    varnish: Child,
    /// caddy's TLS front (HTTP/1.1, HTTP/2, and HTTP/3 on the same UDP port).
    pub tls_port: u16,
    /// varnish (plain HTTP).
    pub edge_port: u16,
    /// caddy's file server (plain HTTP), behind varnish.
    pub origin_port: u16,
    /// caddy's local CA certificate (PEM): trust it with `--ca`.
    pub ca: PathBuf,
}

fn free_port() -> Result<u16> {
    // TCP and UDP free at once (the TLS front also serves HTTP/3).
    for _ in 0..50 {
        let t = TcpListener::bind("127.0.0.1:0")?;
        let p = t.local_addr()?.port();
        if std::net::UdpSocket::bind(("127.0.0.1", p)).is_ok() {
            return Ok(p);
        }
    }
    bail!("no free loopback port")
}

fn wait_port(p: u16, what: &str, child: &mut Child, log: &Path) -> Result<()> {
    let t0 = Instant::now();
    while TcpStream::connect_timeout(
        &SocketAddr::from(([127, 0, 0, 1], p)),
        Duration::from_millis(200),
    )
    .is_err()
    {
        if let Ok(Some(s)) = child.try_wait() {
            bail!(
                "{what} exited ({s}): {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
        if t0.elapsed() > Duration::from_secs(30) {
            bail!(
                "{what} did not listen on 127.0.0.1:{p} in 30 s: {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(())
}

/// Whether `caddy` and `varnishd` can be run.
pub fn available() -> Result<()> {
    for (bin, arg) in [("caddy", "version"), ("varnishd", "-V")] {
        Command::new(bin)
            .arg(arg)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .with_context(|| {
                format!(
                    "{bin} not found (Debian package {})",
                    if bin == "caddy" { "caddy" } else { "varnish" }
                )
            })?;
    }
    Ok(())
}

/// The origin's site block: the published folder with PUBLISH.md's headers.
pub fn caddy_site(root: &Path) -> String {
    format!(
        r#"	root * {root}
	# Objects never change (their name is their SHA-256): cache forever.
	@objects path /chunks/*
	header @objects Cache-Control "public, max-age=31536000, immutable"
	# The manifest changes on re-publish: caches may keep it a few seconds only. It is JSON
	# (~110 bytes a block): gzip makes it ~11x smaller.
	@manifest path */manifest.json
	header @manifest Cache-Control "public, max-age=5"
	encode @manifest gzip
	# The page and its scripts: revalidate.
	@page path / /index.html /app.js /app.css /xr.js
	header @page Cache-Control "no-cache"
	# A page on another origin may read a published scene (it is public by design).
	header Access-Control-Allow-Origin "*"
	header X-Content-Type-Options nosniff
	file_server"#,
        root = root.display()
    )
}

impl Edge {
    /// Serve `site` (a `snerf publish` folder) from caddy behind varnish; configuration and
    /// state go in `dir`.
    pub fn start(site: &Path, dir: &Path, opts: &EdgeOptions) -> Result<Edge> {
        available()?;
        std::fs::create_dir_all(dir)?;
        let dir = dir.canonicalize()?;
        let site = site
            .canonicalize()
            .with_context(|| format!("{}: cannot open", site.display()))?;
        let (tls_port, edge_port, origin_port) = (free_port()?, free_port()?, free_port()?);
        let home = dir.join("caddy-home");
        std::fs::create_dir_all(&home)?;
        let caddyfile = dir.join("Caddyfile");
        std::fs::write(
            &caddyfile,
            format!(
                r#"{{
	admin off
	auto_https disable_redirects
	skip_install_trust
	storage file_system {home}
	log {{
		output discard
	}}
}}
https://127.0.0.1:{tls_port} {{
	tls internal
	reverse_proxy 127.0.0.1:{edge_port} {{
		flush_interval -1
	}}
}}
http://127.0.0.1:{origin_port} {{
{site}
}}
"#,
                home = home.display(),
                site = caddy_site(&site)
            ),
        )?;
        let auth = match &opts.bearer {
            Some(t) => format!(
                "    if (!req.http.Authorization || req.http.Authorization != \"Bearer {t}\") {{ return (synth(401, \"Unauthorized\")); }}\n    unset req.http.Authorization;\n"
            ),
            None => String::new(),
        };
        let vcl = dir.join("edge.vcl");
        std::fs::write(
            &vcl,
            format!(
                r#"vcl 4.1;
backend origin {{ .host = "127.0.0.1"; .port = "{origin_port}"; }}
sub vcl_recv {{
    if (req.method != "GET" && req.method != "HEAD") {{ return (synth(405, "Method Not Allowed")); }}
{auth}    return (hash);
}}
sub vcl_hash {{
    hash_data(req.url);
    return (lookup);
}}
"#
            ),
        )?;
        let clog = dir.join("caddy.log");
        let mut caddy = Command::new("caddy")
            .args(["run", "--adapter", "caddyfile", "--config"])
            .arg(&caddyfile)
            .env("HOME", &home)
            .env("XDG_DATA_HOME", &home)
            .env("XDG_CONFIG_HOME", &home)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&clog)?)
            .stderr(std::fs::File::create(dir.join("caddy.err"))?)
            .spawn()
            .context("starting caddy")?;
        let vlog = dir.join("varnish.log");
        let varnish = Command::new("varnishd")
            .args([
                "-F",
                "-j",
                "none",
                "-s",
                "malloc,512m",
                "-p",
                "thread_pool_min=50",
                "-a",
            ])
            .arg(format!("127.0.0.1:{edge_port}"))
            .arg("-f")
            .arg(&vcl)
            .arg("-n")
            .arg(dir.join("varnish"))
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&vlog)?)
            .stderr(std::fs::File::create(dir.join("varnish.err"))?)
            .spawn();
        let varnish = match varnish {
            Ok(v) => v,
            Err(e) => {
                let _ = caddy.kill();
                let _ = caddy.wait();
                return Err(e).context("starting varnishd");
            }
        };
        let mut edge = Edge {
            dir: dir.clone(),
            caddy,
            varnish,
            tls_port,
            edge_port,
            origin_port,
            ca: home.join("pki/authorities/local/root.crt"),
        };
        wait_port(
            origin_port,
            "caddy",
            &mut edge.caddy,
            &dir.join("caddy.err"),
        )?;
        wait_port(tls_port, "caddy", &mut edge.caddy, &dir.join("caddy.err"))?;
        wait_port(
            edge_port,
            "varnishd",
            &mut edge.varnish,
            &dir.join("varnish.err"),
        )?;
        let t0 = Instant::now();
        while !edge.ca.exists() {
            if t0.elapsed() > Duration::from_secs(30) {
                bail!("caddy wrote no CA certificate at {}", edge.ca.display());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(edge)
    }

    pub fn https_url(&self, path: &str) -> String {
        format!("https://127.0.0.1:{}{path}", self.tls_port)
    }
    pub fn edge_url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}{path}", self.edge_port)
    }
    pub fn origin_url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}{path}", self.origin_port)
    }

    /// varnish's counters (`varnishstat -1`): name -> value.
    pub fn counters(&self) -> Result<std::collections::BTreeMap<String, u64>> {
        let out = Command::new("varnishstat")
            .arg("-1")
            .arg("-n")
            .arg(self.dir.join("varnish"))
            .output()
            .context("varnishstat")?;
        let mut m = std::collections::BTreeMap::new();
        for l in String::from_utf8_lossy(&out.stdout).lines() {
            let mut f = l.split_whitespace();
            if let (Some(k), Some(v)) = (f.next(), f.next().and_then(|v| v.parse().ok())) {
                m.insert(k.to_string(), v);
            }
        }
        Ok(m)
    }

    /// Drop everything varnish holds (a cold edge).
    pub fn purge(&self) -> Result<()> {
        let s = Command::new("varnishadm")
            .arg("-n")
            .arg(self.dir.join("varnish"))
            .args(["ban", "req.url ~ ."])
            .output()
            .context("varnishadm")?;
        if !s.status.success() {
            bail!("varnishadm ban: {}", String::from_utf8_lossy(&s.stdout));
        }
        Ok(())
    }
}

impl Drop for Edge {
    fn drop(&mut self) {
        // varnishd's manager stops its cache process on SIGTERM (SIGKILL would orphan it).
        for c in [&mut self.varnish, &mut self.caddy] {
            let _ = Command::new("kill")
                .arg("-TERM")
                .arg(c.id().to_string())
                .status();
            let t0 = Instant::now();
            while matches!(c.try_wait(), Ok(None)) && t0.elapsed() < Duration::from_secs(5) {
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
