//! `quic://HOST[:PORT]/ASSET` URLs.

use anyhow::{anyhow, bail, ensure, Result};
use std::net::{SocketAddr, ToSocketAddrs};

use crate::proto::{valid_asset_name, DEFAULT_PORT};

/// Split `quic://HOST[:PORT]/ASSET` into (`host:port`, asset name). HOST is a DNS name, an
/// IPv4 address or a bracketed IPv6 address; PORT defaults to 4433; ASSET may be empty (the
/// server's only asset) and may carry a `.snerf` suffix.
pub fn parse_url(url: &str) -> Result<(String, String)> {
    let rest = url
        .strip_prefix("quic://")
        .ok_or_else(|| anyhow!("{:?}: a stream URL looks like quic://HOST:PORT/ASSET", url))?;
    let (auth, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i + 1..]),
        None => (rest, ""),
    };
    ensure!(
        !auth.is_empty(),
        "{:?}: missing host (quic://HOST:PORT/ASSET)",
        url
    );
    ensure!(
        !auth.contains('@'),
        "{:?}: user info is not supported; pass the token with --token",
        url
    );
    let (host, port) = if let Some(r) = auth.strip_prefix('[') {
        let end = r
            .find(']')
            .ok_or_else(|| anyhow!("{:?}: unterminated [IPv6] host", url))?;
        let host = &r[..end];
        host.parse::<std::net::Ipv6Addr>()
            .map_err(|_| anyhow!("{:?}: {:?} is not an IPv6 address", url, host))?;
        let after = &r[end + 1..];
        let port = match after.strip_prefix(':') {
            Some(p) => Some(p),
            None if after.is_empty() => None,
            None => bail!("{:?}: unexpected {:?} after the IPv6 host", url, after),
        };
        (format!("[{}]", host), port)
    } else {
        match auth.rsplit_once(':') {
            Some((h, p)) => (h.to_string(), Some(p)),
            None => (auth.to_string(), None),
        }
    };
    ensure!(!host.is_empty() && host != "[]", "{:?}: missing host", url);
    ensure!(
        host.starts_with('[')
            || host
                .bytes()
                .all(|c| c.is_ascii_alphanumeric() || c == b'.' || c == b'-'),
        "{:?}: {:?} is not a valid host name",
        url,
        host
    );
    let port = match port {
        None => DEFAULT_PORT,
        Some(p) => match p.parse::<u16>() {
            Ok(0) | Err(_) => bail!("{:?}: port {:?} must be a number in 1..=65535", url, p),
            Ok(p) => p,
        },
    };
    let asset = path.trim_end_matches('/');
    let asset = asset.strip_suffix(".snerf").unwrap_or(asset);
    ensure!(
        !asset.contains('?') && !asset.contains('#'),
        "{:?}: query strings are not supported",
        url
    );
    ensure!(
        asset.is_empty() || valid_asset_name(asset),
        "{:?}: asset name {:?} may only use letters, digits, '.', '_' and '-' (no '/', not starting with '.')",
        url,
        asset
    );
    Ok((format!("{}:{}", host, port), asset.to_string()))
}

/// Resolve `host:port` (blocking DNS for names) to the first address.
pub fn resolve(host_port: &str) -> Result<SocketAddr> {
    if let Ok(a) = host_port.parse::<SocketAddr>() {
        return Ok(a);
    }
    host_port
        .to_socket_addrs()
        .map_err(|e| anyhow!("cannot resolve {}: {}", host_port, e))?
        .next()
        .ok_or_else(|| anyhow!("{} resolves to no address", host_port))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(
            parse_url("quic://127.0.0.1:4433/scene").unwrap(),
            ("127.0.0.1:4433".into(), "scene".into())
        );
        assert_eq!(
            parse_url("quic://host.example/scene.snerf").unwrap(),
            ("host.example:4433".into(), "scene".into())
        );
        assert_eq!(
            parse_url("quic://[::1]:9/a_b-c.d").unwrap(),
            ("[::1]:9".into(), "a_b-c.d".into())
        );
        assert_eq!(parse_url("quic://h:1").unwrap(), ("h:1".into(), "".into()));
        assert_eq!(parse_url("quic://h:1/").unwrap(), ("h:1".into(), "".into()));
        for bad in [
            "http://h:1/a",
            "quic://",
            "quic://:5/a",
            "quic://h:0/a",
            "quic://h:99999/a",
            "quic://h:x/a",
            "quic://h:1/../a",
            "quic://h:1/a/b",
            "quic://h:1/.hidden",
            "quic://u@h:1/a",
            "quic://[::1/a",
            "quic://[nope]:1/a",
            "quic://h h:1/a",
            "quic://h:1/a?x=1",
        ] {
            let e = parse_url(bad);
            assert!(e.is_err(), "{} should fail", bad);
            assert!(
                format!("{:#}", e.unwrap_err()).contains(bad),
                "error should quote the URL"
            );
        }
        assert_eq!(
            resolve("127.0.0.1:5").unwrap(),
            "127.0.0.1:5".parse().unwrap()
        );
        assert!(resolve("localhost:5").unwrap().ip().is_loopback());
    }
}
