//! TLS 1.3 for `snerf/1`: the server's self-signed certificate and access token (created on
//! first run in a state directory), and the client's fingerprint-pinning verifier. There is
//! no CA: the client trusts exactly the certificate whose SHA-256 it was given.

use anyhow::{anyhow, bail, ensure, Context, Result};
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::{verify_tls12_signature, verify_tls13_signature, CryptoProvider};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName, UnixTime};
use rustls::{DigitallySignedStruct, SignatureScheme};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::proto::{from_hex, to_hex, ALPN};

/// The server's identity: certificate chain, key, the end-entity fingerprint and the token.
pub struct Identity {
    pub certs: Vec<CertificateDer<'static>>,
    pub key: PrivateKeyDer<'static>,
    /// Lowercase hex SHA-256 of the end-entity certificate's DER.
    pub fingerprint: String,
    pub token: String,
    /// True if this call created the certificate or token (first run).
    pub created: bool,
}

pub fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

/// Lowercase hex SHA-256 of a DER certificate.
pub fn fingerprint(der: &[u8]) -> String {
    to_hex(&Sha256::digest(der))
}

/// Accepts `ab12…`, `AB:12:…`, `sha256:ab12…`; returns 32 bytes.
pub fn parse_pin(pin: &str) -> Result<[u8; 32]> {
    let p = pin.trim();
    let p = p
        .strip_prefix("sha256:")
        .or_else(|| p.strip_prefix("SHA256:"))
        .unwrap_or(p);
    let hex: String = p.chars().filter(|c| *c != ':').collect();
    let b = from_hex(&hex)
        .map_err(|e| anyhow!("pin {:?} is not a hex SHA-256 fingerprint: {}", pin, e))?;
    ensure!(
        b.len() == 32,
        "pin {:?} has {} bytes, a SHA-256 fingerprint has 32 (64 hex digits)",
        pin,
        b.len()
    );
    let mut out = [0u8; 32];
    out.copy_from_slice(&b);
    Ok(out)
}

/// Random hex token of `bytes` bytes from the OS RNG.
pub fn random_token(bytes: usize) -> Result<String> {
    let mut b = vec![0u8; bytes];
    getrandom::fill(&mut b).map_err(|e| anyhow!("OS random generator failed: {}", e))?;
    Ok(to_hex(&b))
}

/// Default state directory: $XDG_CONFIG_HOME/snerf/serve or ~/.config/snerf/serve, else
/// `.snerf-serve` next to the assets.
pub fn default_state_dir(assets: &Path) -> PathBuf {
    if let Some(x) = std::env::var_os("XDG_CONFIG_HOME").filter(|x| !x.is_empty()) {
        return PathBuf::from(x).join("snerf").join("serve");
    }
    if let Some(h) = std::env::var_os("HOME").filter(|x| !x.is_empty()) {
        return PathBuf::from(h).join(".config").join("snerf").join("serve");
    }
    let base = if assets.is_dir() {
        assets.to_path_buf()
    } else {
        assets.parent().map(Path::to_path_buf).unwrap_or_default()
    };
    base.join(".snerf-serve")
}

pub(crate) fn write_private(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let tmp = path.with_extension("tmp");
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.mode(0o600);
    }
    let mut f = o
        .open(&tmp)
        .with_context(|| format!("{}: cannot create", tmp.display()))?;
    f.write_all(bytes)
        .and_then(|_| f.sync_all())
        .with_context(|| format!("{}: cannot write", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("{}: cannot rename into place", path.display()))?;
    Ok(())
}

fn load_certs(path: &Path) -> Result<Vec<CertificateDer<'static>>> {
    let bytes = std::fs::read(path)
        .with_context(|| format!("{}: cannot read certificate", path.display()))?;
    let certs: Vec<CertificateDer<'static>> = if bytes.starts_with(b"-----") {
        CertificateDer::pem_slice_iter(&bytes)
            .collect::<Result<_, _>>()
            .map_err(|e| anyhow!("{}: bad PEM certificate: {:?}", path.display(), e))?
    } else {
        vec![CertificateDer::from(bytes)]
    };
    ensure!(
        !certs.is_empty(),
        "{}: no certificate found",
        path.display()
    );
    Ok(certs)
}

fn load_key(path: &Path) -> Result<PrivateKeyDer<'static>> {
    let bytes = std::fs::read(path)
        .with_context(|| format!("{}: cannot read private key", path.display()))?;
    if bytes.starts_with(b"-----") {
        PrivateKeyDer::from_pem_slice(&bytes)
            .map_err(|e| anyhow!("{}: bad PEM private key: {:?}", path.display(), e))
    } else {
        PrivateKeyDer::try_from(bytes)
            .map_err(|e| anyhow!("{}: bad DER private key: {}", path.display(), e))
    }
}

fn load_token(path: &Path) -> Result<String> {
    let t = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read token", path.display()))?;
    let t = t.trim().to_string();
    ensure!(
        t.len() >= 16,
        "{}: token is {} characters, need at least 16",
        path.display(),
        t.len()
    );
    ensure!(
        t.len() <= crate::proto::MAX_TOKEN_LEN,
        "{}: token longer than {} characters",
        path.display(),
        crate::proto::MAX_TOKEN_LEN
    );
    ensure!(
        t.bytes().all(|c| c.is_ascii_graphic()),
        "{}: token must be printable ASCII without spaces",
        path.display()
    );
    Ok(t)
}

/// Load or create the server identity. `cert`+`key` given: use them (both or neither).
/// Otherwise `state/cert.pem` + `state/key.pem`, generated (self-signed, ECDSA P-256) if
/// absent. Token: `token_file` if given, else `state/token`, generated (32 random bytes,
/// hex) if absent.
pub fn load_or_create_identity(
    state: &Path,
    cert: Option<&Path>,
    key: Option<&Path>,
    token_file: Option<&Path>,
) -> Result<Identity> {
    let mut created = false;
    let (certs, key) = match (cert, key) {
        (Some(c), Some(k)) => (load_certs(c)?, load_key(k)?),
        (None, None) => {
            std::fs::create_dir_all(state)
                .with_context(|| format!("{}: cannot create state directory", state.display()))?;
            let (cp, kp) = (state.join("cert.pem"), state.join("key.pem"));
            if !cp.exists() || !kp.exists() {
                let ck = rcgen::generate_simple_self_signed(vec![
                    "snerf".to_string(),
                    "localhost".to_string(),
                ])
                .map_err(|e| anyhow!("cannot generate a self-signed certificate: {}", e))?;
                write_private(&kp, ck.signing_key.serialize_pem().as_bytes())?;
                write_private(&cp, ck.cert.pem().as_bytes())?;
                created = true;
            }
            (load_certs(&cp)?, load_key(&kp)?)
        }
        _ => bail!("--cert and --key must be given together"),
    };
    let token = match token_file {
        Some(t) => load_token(t)?,
        None => {
            std::fs::create_dir_all(state)
                .with_context(|| format!("{}: cannot create state directory", state.display()))?;
            let tp = state.join("token");
            if !tp.exists() {
                write_private(&tp, format!("{}\n", random_token(32)?).as_bytes())?;
                created = true;
            }
            load_token(&tp)?
        }
    };
    let fingerprint = fingerprint(&certs[0]);
    Ok(Identity {
        certs,
        key,
        fingerprint,
        token,
        created,
    })
}

pub fn server_crypto(id: &Identity) -> Result<quinn::crypto::rustls::QuicServerConfig> {
    let mut cfg = rustls::ServerConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| anyhow!("TLS setup: {}", e))?
        .with_no_client_auth()
        .with_single_cert(id.certs.clone(), id.key.clone_key())
        .map_err(|e| {
            anyhow!(
                "certificate and key do not form a usable TLS identity: {}",
                e
            )
        })?;
    cfg.alpn_protocols = vec![ALPN.to_vec()];
    cfg.max_early_data_size = 0;
    quinn::crypto::rustls::QuicServerConfig::try_from(cfg)
        .map_err(|e| anyhow!("QUIC TLS setup: {}", e))
}

/// Verifies the server by the SHA-256 of its end-entity certificate only (and, as always in
/// TLS, that the server holds that certificate's key: handshake signatures are checked).
#[derive(Debug)]
pub struct PinVerifier {
    pin: [u8; 32],
    provider: Arc<CryptoProvider>,
    /// Set when a certificate with another fingerprint was presented.
    pub mismatch: Mutex<Option<String>>,
}

impl PinVerifier {
    pub fn new(pin: [u8; 32]) -> PinVerifier {
        PinVerifier {
            pin,
            provider: provider(),
            mismatch: Mutex::new(None),
        }
    }
    pub fn mismatch_message(&self) -> Option<String> {
        self.mismatch.lock().ok().and_then(|m| m.clone())
    }
}

impl ServerCertVerifier for PinVerifier {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let got: [u8; 32] = Sha256::digest(end_entity.as_ref()).into();
        // Constant-time compare (the pin is not secret, but it costs nothing).
        let diff = got
            .iter()
            .zip(self.pin.iter())
            .fold(0u8, |a, (x, y)| a | (x ^ y));
        if diff == 0 {
            Ok(ServerCertVerified::assertion())
        } else {
            let msg = format!(
                "server certificate fingerprint {} does not match the pinned fingerprint {}",
                to_hex(&got),
                to_hex(&self.pin)
            );
            if let Ok(mut m) = self.mismatch.lock() {
                *m = Some(msg.clone());
            }
            Err(rustls::Error::General(msg))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls12_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls13_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.provider
            .signature_verification_algorithms
            .supported_schemes()
    }
}

pub fn client_crypto(
    verifier: Arc<PinVerifier>,
) -> Result<quinn::crypto::rustls::QuicClientConfig> {
    let mut cfg = rustls::ClientConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| anyhow!("TLS setup: {}", e))?
        .dangerous()
        .with_custom_certificate_verifier(verifier)
        .with_no_client_auth();
    cfg.alpn_protocols = vec![ALPN.to_vec()];
    cfg.enable_early_data = false;
    quinn::crypto::rustls::QuicClientConfig::try_from(cfg)
        .map_err(|e| anyhow!("QUIC TLS setup: {}", e))
}

/// Constant-time token comparison.
pub fn token_eq(a: &str, b: &str) -> bool {
    let (ha, hb): ([u8; 32], [u8; 32]) = (
        Sha256::digest(a.as_bytes()).into(),
        Sha256::digest(b.as_bytes()).into(),
    );
    ha.iter()
        .zip(hb.iter())
        .fold(0u8, |acc, (x, y)| acc | (x ^ y))
        == 0
}
