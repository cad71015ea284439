//! The web viewer's generated certificate, kept in the server's state directory and used again
//! on the next start while it still holds every name this machine needs and is not due for
//! renewal: a headset whose person clicked through the browser's warning once is not asked
//! again because the laptop restarted. Renewed every `Limits::web_cert_rotate` (browsers take
//! a pinned WebTransport hash only for a certificate valid at most 14 days).
//!
//! Files: `web-cert.der`, `web-key.der` (mode 0600) and `web-cert.json` (`{names, created,
//! sha256}`, the names it was made for, its creation in Unix seconds and the certificate's
//! SHA-256, so a replaced or damaged file is never used).

use anyhow::{anyhow, Result};
use rustls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};
use std::path::Path;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Validity of a generated certificate (browsers require ≤ 14 days for pinned hashes).
pub const CERT_DAYS: u32 = 13;

/// A generated certificate: DER, key, hex SHA-256, and when it was made.
pub(crate) struct Generated {
    pub cert: CertificateDer<'static>,
    pub key: PrivateKeyDer<'static>,
    pub sha256: String,
    pub created: SystemTime,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Meta {
    names: Vec<String>,
    created: u64,
    sha256: String,
}

/// A fresh self-signed ECDSA P-256 certificate valid for `CERT_DAYS`, for `names` (DNS names
/// and IP addresses).
pub(crate) fn generate(names: &[String]) -> Result<Generated> {
    let g = wtransport::Identity::self_signed_builder()
        .subject_alt_names(names.iter().cloned())
        .from_now_utc()
        .validity_days(CERT_DAYS)
        .build()
        .map_err(|e| anyhow!("cannot generate the web viewer's certificate: {}", e))?;
    let der = g.certificate_chain().as_slice()[0].der().to_vec();
    let sha256 = crate::tls::fingerprint(&der);
    let key = PrivateKeyDer::Pkcs8(PrivatePkcs8KeyDer::from(g.private_key().secret_der().to_vec()));
    Ok(Generated { cert: CertificateDer::from(der), key, sha256, created: SystemTime::now() })
}

/// The kept certificate when it holds every one of `names` and is younger than `renew`;
/// otherwise a new one, kept for next time (a state directory that cannot be written only
/// costs the reuse, and is said).
pub(crate) fn kept_or_new(state: &Path, names: &[String], renew: Duration) -> Result<Generated> {
    if let Some(g) = load(state, names, renew) {
        return Ok(g);
    }
    let g = generate(names)?;
    if let Err(e) = store(state, names, &g) {
        eprintln!("snerf serve: cannot keep the web viewer's certificate in {}: {e:#}", state.display());
    }
    Ok(g)
}

/// Keep `g` (made for `names`) for the next start.
pub(crate) fn store(state: &Path, names: &[String], g: &Generated) -> Result<()> {
    std::fs::create_dir_all(state).map_err(|e| anyhow!("{}: {e}", state.display()))?;
    let created = g.created.duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    crate::tls::write_private(&state.join("web-cert.der"), g.cert.as_ref())?;
    crate::tls::write_private(&state.join("web-key.der"), g.key.secret_der())?;
    let meta = Meta { names: names.to_vec(), created, sha256: g.sha256.clone() };
    crate::tls::write_private(&state.join("web-cert.json"), serde_json::to_string(&meta)?.as_bytes())
}

fn load(state: &Path, names: &[String], renew: Duration) -> Option<Generated> {
    let meta: Meta = serde_json::from_slice(&std::fs::read(state.join("web-cert.json")).ok()?).ok()?;
    let created = UNIX_EPOCH + Duration::from_secs(meta.created);
    let age = SystemTime::now().duration_since(created).ok()?;
    if age >= renew || !names.iter().all(|n| meta.names.contains(n)) {
        return None;
    }
    let der = std::fs::read(state.join("web-cert.der")).ok()?;
    if crate::tls::fingerprint(&der) != meta.sha256 {
        return None;
    }
    let key = PrivateKeyDer::try_from(std::fs::read(state.join("web-key.der")).ok()?).ok()?;
    Some(Generated { cert: CertificateDer::from(der), key, sha256: meta.sha256, created })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kept_certificate_is_used_again_only_while_it_fits() {
        let dir = std::env::temp_dir().join(format!("snerf-web-cert-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let names = vec!["localhost".to_string(), "10.0.0.2".into()];
        let day = Duration::from_secs(86400);
        let a = kept_or_new(&dir, &names, day).unwrap();
        // The same names (or fewer): the same certificate.
        assert_eq!(kept_or_new(&dir, &names, day).unwrap().sha256, a.sha256);
        assert_eq!(kept_or_new(&dir, &names[..1], day).unwrap().sha256, a.sha256);
        // A name it lacks (a new LAN address): a new one, kept from then on.
        let more = vec!["localhost".to_string(), "10.0.0.2".into(), "192.168.1.5".into()];
        let b = kept_or_new(&dir, &more, day).unwrap();
        assert_ne!(b.sha256, a.sha256);
        assert_eq!(kept_or_new(&dir, &more, day).unwrap().sha256, b.sha256);
        // Due for renewal: a new one.
        assert_ne!(kept_or_new(&dir, &more, Duration::ZERO).unwrap().sha256, b.sha256);
        // A replaced certificate file is not used.
        let c = kept_or_new(&dir, &more, day).unwrap();
        std::fs::write(dir.join("web-cert.der"), b"not a certificate").unwrap();
        assert_ne!(kept_or_new(&dir, &more, day).unwrap().sha256, c.sha256);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
