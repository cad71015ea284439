//! Wire format of `snerf/1` (see PROTOCOL.md): length-prefixed JSON control messages, the
//! binary pose datagram, and the chunk records of the data streams. Every decoder here takes
//! untrusted bytes and returns an error instead of panicking (property-tested and fuzzed).

use anyhow::{anyhow, bail, ensure, Result};
use serde::{Deserialize, Serialize};
use tokio::io::{AsyncRead, AsyncReadExt};

/// ALPN of this protocol version. A future incompatible protocol gets `snerf/2`.
pub const ALPN: &[u8] = b"snerf/1";
/// Protocol version carried in `Hello` (must match the ALPN's).
pub const PROTOCOL_VERSION: u32 = 1;
/// Default UDP port.
pub const DEFAULT_PORT: u16 = 4433;

/// Socket buffer size asked for (the kernel caps it at net.core.rmem_max / wmem_max). The
/// default ~208 KiB receive buffer overflows at a few hundred MB/s and QUIC reads that loss
/// as congestion.
pub const SOCKET_BUFFER: usize = 8 << 20;

/// A UDP socket bound to `addr` with large send/receive buffers (best effort).
pub fn udp_socket(addr: std::net::SocketAddr) -> std::io::Result<std::net::UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let s = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
    if addr.is_ipv6() {
        let _ = s.set_only_v6(false);
    }
    let _ = s.set_recv_buffer_size(SOCKET_BUFFER);
    let _ = s.set_send_buffer_size(SOCKET_BUFFER);
    s.bind(&addr.into())?;
    Ok(s.into())
}

/// Largest token, asset name and `have` list a server accepts in a Hello.
pub const MAX_TOKEN_LEN: usize = 256;
pub const MAX_NAME_LEN: usize = 255;
pub const MAX_HAVE_RANGES: usize = 1 << 16;

/// Application error codes used when closing a connection (QUIC CONNECTION_CLOSE, app space).
pub mod code {
    /// Normal close: the client has everything / is leaving.
    pub const DONE: u32 = 0;
    /// A message arrived that is not allowed in the current state (e.g. List before Hello).
    pub const PROTOCOL: u32 = 1;
    /// Wrong access token.
    pub const UNAUTHORIZED: u32 = 2;
    /// No such asset.
    pub const NOT_FOUND: u32 = 3;
    /// A control message or frame that does not decode.
    pub const MALFORMED: u32 = 4;
    /// A control message larger than the server's limit.
    pub const TOO_LARGE: u32 = 5;
    /// Server at its client limit.
    pub const BUSY: u32 = 6;
    /// Hello not received in time, or the client stopped reading (send stalled).
    pub const TIMEOUT: u32 = 7;
    /// Unsupported protocol version in Hello.
    pub const VERSION: u32 = 8;
    /// The server could not read or validate the asset.
    pub const INTERNAL: u32 = 9;
    /// The server is shutting down.
    pub const SHUTDOWN: u32 = 10;
    /// The client rejected data the server sent (bad chunk, bad message).
    pub const CLIENT_REJECT: u32 = 11;

    pub fn name(c: u64) -> &'static str {
        match c as u32 {
            DONE => "done",
            PROTOCOL => "protocol violation",
            UNAUTHORIZED => "unauthorized",
            NOT_FOUND => "not found",
            MALFORMED => "malformed message",
            TOO_LARGE => "message too large",
            BUSY => "server busy",
            TIMEOUT => "timeout",
            VERSION => "unsupported version",
            INTERNAL => "internal server error",
            SHUTDOWN => "server shutting down",
            CLIENT_REJECT => "client rejected data",
            _ => "unknown",
        }
    }
}

/// A viewer pose: where the eye is and where it looks (world space), the playback time of a
/// dynamic asset, and the diagonal field of view in degrees (0 = default).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub eye: [f32; 3],
    pub forward: [f32; 3],
    #[serde(default)]
    pub time: f32,
    #[serde(default)]
    pub fov_deg: f32,
}

impl Pose {
    pub fn new(eye: [f32; 3], forward: [f32; 3]) -> Pose {
        Pose {
            eye,
            forward,
            time: 0.0,
            fov_deg: 0.0,
        }
    }

    /// Finite eye, finite non-zero forward, finite time, fov in [0, 180).
    pub fn validate(&self) -> Result<()> {
        ensure!(
            self.eye.iter().all(|x| x.is_finite()),
            "pose eye is not finite"
        );
        ensure!(
            self.forward.iter().all(|x| x.is_finite()),
            "pose forward is not finite"
        );
        let n2: f32 = self.forward.iter().map(|x| x * x).sum();
        ensure!(n2 > 1e-12 && n2.is_finite(), "pose forward is zero");
        ensure!(self.time.is_finite(), "pose time is not finite");
        ensure!(
            self.fov_deg.is_finite() && (0.0..180.0).contains(&self.fov_deg),
            "pose fov {} not in [0,180)",
            self.fov_deg
        );
        Ok(())
    }
}

/// Size of the pose datagram.
pub const POSE_DATAGRAM_LEN: usize = 40;
const POSE_MAGIC: [u8; 2] = *b"SP";

/// Pose datagram: b"SP", u8 version (1), u8 flags (0), u32 seq, eye 3xf32, forward 3xf32,
/// time f32, fov_deg f32 (little-endian). Later seq wins; older ones are ignored.
pub fn encode_pose(seq: u32, p: &Pose) -> [u8; POSE_DATAGRAM_LEN] {
    let mut b = [0u8; POSE_DATAGRAM_LEN];
    b[..2].copy_from_slice(&POSE_MAGIC);
    b[2] = 1;
    b[4..8].copy_from_slice(&seq.to_le_bytes());
    let vals = [
        p.eye[0],
        p.eye[1],
        p.eye[2],
        p.forward[0],
        p.forward[1],
        p.forward[2],
        p.time,
        p.fov_deg,
    ];
    for (i, v) in vals.iter().enumerate() {
        b[8 + 4 * i..12 + 4 * i].copy_from_slice(&v.to_le_bytes());
    }
    b
}

pub fn decode_pose(b: &[u8]) -> Result<(u32, Pose)> {
    ensure!(
        b.len() == POSE_DATAGRAM_LEN,
        "pose datagram has {} bytes, expected {}",
        b.len(),
        POSE_DATAGRAM_LEN
    );
    ensure!(b[..2] == POSE_MAGIC, "pose datagram has bad magic");
    ensure!(
        b[2] == 1 && b[3] == 0,
        "pose datagram version {} flags {} unsupported",
        b[2],
        b[3]
    );
    let seq = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
    let f =
        |i: usize| f32::from_le_bytes([b[8 + 4 * i], b[9 + 4 * i], b[10 + 4 * i], b[11 + 4 * i]]);
    let p = Pose {
        eye: [f(0), f(1), f(2)],
        forward: [f(3), f(4), f(5)],
        time: f(6),
        fov_deg: f(7),
    };
    p.validate()?;
    Ok((seq, p))
}

/// Client -> server control messages.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ClientMsg {
    /// First message, exactly once. `asset` None = authenticate only (then List).
    Hello {
        version: u32,
        token: String,
        #[serde(default)]
        asset: Option<String>,
        /// Chunk-index ranges [lo, hi) the client already holds (resume).
        #[serde(default)]
        have: Vec<[u32; 2]>,
        /// The `sha256` of the asset the `have` ranges refer to; a mismatch ignores `have`.
        #[serde(default)]
        resume_id: Option<String>,
        #[serde(default)]
        pose: Option<Pose>,
        /// A style switch: the client holds a complete style of the multi-style file whose
        /// `AssetInfo::geometry` this is, and asks for `asset`'s colour part only (its view
        /// MLP and per block its colour), which it writes over the colour it holds.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        colour_of: Option<String>,
    },
    /// Ask the server to train the painting `painting` (a key its listing offers for `asset`,
    /// `ListEntry::paintings`) as a new style of `asset` (after Hello). Answered `Training`;
    /// the style is announced (`Styles`) once it is added.
    AddStyle {
        asset: String,
        painting: String,
    },
    /// Ask for the asset list (after Hello); with `thumbs`, each entry carries a thumbnail.
    /// With `watch`, the server also sends a `Styles` message whenever a served asset gains a
    /// style, for as long as this session lasts (a server that predates `watch` ignores it).
    List {
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        thumbs: bool,
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        watch: bool,
    },
}

/// One entry of a listing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ListEntry {
    pub name: String,
    pub size: u64,
    /// Scene kind from the asset's header (`object`, `forward`, `unbounded`), when readable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
    /// The start view, when the client asked for thumbnails and the file could be rendered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thumb: Option<Thumb>,
    /// A multi-style asset's styles as its header lists them (name, source, swatch colour):
    /// `name` streams the first, `name.STYLE` each (`plan::ServedStyle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub styles: Option<Vec<snerf_asset::StyleInfo>>,
    /// Paintings the server offers to train as new styles of this asset (`AddStyle`), by
    /// key (`snerf serve --styles-dir`: the installed paintings the asset has no style of).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paintings: Option<Vec<String>>,
}

/// A small picture: `width` x `height` RGB8 pixels, row-major from the top, base64.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Thumb {
    pub width: u32,
    pub height: u32,
    pub rgb: String,
}

/// What the server is about to stream.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AssetInfo {
    pub name: String,
    /// File size in bytes.
    pub size: u64,
    /// Number of chunks in the file (HEAD .. END).
    pub chunks: u32,
    /// Hex SHA-256 of the whole file: resume id and end-to-end check.
    pub sha256: String,
    /// Hex of the file's 16-byte preamble.
    pub preamble: String,
    pub atlas_blocks: u32,
    pub frames: u32,
    /// One style of a multi-style file: the id of the geometry its styles share
    /// (`plan::geometry_id`: a hex SHA-256 of the file's header without its style list, grids
    /// and density, so a style added to the file later keeps it). A client holding this asset
    /// may switch to another of its styles by colour alone (`Hello::colour_of`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<String>,
}

/// Server -> client control messages.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMsg {
    Welcome {
        version: u32,
        #[serde(default)]
        asset: Option<AssetInfo>,
        /// Whether the Hello's `have` was honoured (same sha256).
        #[serde(default)]
        resumed: bool,
        /// Chunks that will be sent on this connection.
        #[serde(default)]
        sending_chunks: u32,
        /// Their record bytes.
        #[serde(default)]
        sending_bytes: u64,
        /// The answer to a `colour_of` hello: the records are the style's colour part
        /// (`SMLP`, `SCOL` chunks) under the index of the chunk each rewrites, no END.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        colour_only: bool,
    },
    Listing {
        assets: Vec<ListEntry>,
    },
    /// To a session that asked for a listing with `watch`: the multi-style asset `asset` now
    /// has these styles (all of them, in its header's order; `asset.STYLE` streams each).
    Styles {
        asset: String,
        styles: Vec<snerf_asset::StyleInfo>,
    },
    /// The answer to `AddStyle`: the painting is queued to be trained as the style `style` of
    /// `asset` (a `Styles` message follows once it is added, to sessions that watch).
    Training {
        asset: String,
        style: String,
    },
}

pub fn decode_client_msg(b: &[u8]) -> Result<ClientMsg> {
    let m: ClientMsg =
        serde_json::from_slice(b).map_err(|e| anyhow!("bad control message: {}", e))?;
    if let ClientMsg::Hello {
        token,
        asset,
        have,
        resume_id,
        pose,
        colour_of,
        ..
    } = &m
    {
        ensure!(
            token.len() <= MAX_TOKEN_LEN,
            "token longer than {} bytes",
            MAX_TOKEN_LEN
        );
        if let Some(a) = asset {
            ensure!(
                a.len() <= MAX_NAME_LEN,
                "asset name longer than {} bytes",
                MAX_NAME_LEN
            );
        }
        ensure!(
            have.len() <= MAX_HAVE_RANGES,
            "have has {} ranges (max {})",
            have.len(),
            MAX_HAVE_RANGES
        );
        ensure!(
            have.iter().all(|r| r[0] <= r[1]),
            "have has a range with lo > hi"
        );
        if let Some(r) = resume_id {
            ensure!(r.len() <= 128, "resume_id too long");
        }
        if let Some(g) = colour_of {
            ensure!(g.len() <= 128, "colour_of too long");
        }
        if let Some(p) = pose {
            p.validate()?;
        }
    }
    if let ClientMsg::AddStyle { asset, painting } = &m {
        ensure!(valid_asset_name(asset), "add_style: invalid asset name");
        ensure!(
            !painting.is_empty() && painting.len() <= 64 && painting.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-' || b == b'_'),
            "add_style: a painting is named by its key (a-z, 0-9, - and _)"
        );
    }
    Ok(m)
}

pub fn decode_server_msg(b: &[u8]) -> Result<ServerMsg> {
    let m: ServerMsg =
        serde_json::from_slice(b).map_err(|e| anyhow!("bad server message: {}", e))?;
    if let ServerMsg::Styles { asset, styles } = &m {
        ensure!(valid_asset_name(asset), "bad asset name in Styles");
        ensure!(styles.iter().all(|s| valid_asset_name(&format!("{asset}.{}", s.name))), "bad style name in Styles");
    }
    if let ServerMsg::Welcome { asset: Some(a), .. } = &m {
        ensure!(a.chunks >= 2, "asset has {} chunks", a.chunks);
        ensure!(a.size <= 1 << 40, "asset size {} implausible", a.size);
        ensure!(
            a.sha256.len() == 64 && from_hex(&a.sha256).is_ok(),
            "bad sha256 in Welcome"
        );
        ensure!(
            a.preamble.len() == 32 && from_hex(&a.preamble).is_ok(),
            "bad preamble in Welcome"
        );
        ensure!(valid_asset_name(&a.name), "bad asset name in Welcome");
    }
    Ok(m)
}

/// Encode one framed control message: u32 LE length, then JSON.
pub fn encode_frame<T: Serialize>(m: &T) -> Vec<u8> {
    let json = serde_json::to_vec(m).expect("control messages serialize");
    let mut out = Vec::with_capacity(4 + json.len());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out
}

/// Why a frame could not be read.
#[derive(Debug)]
pub enum FrameError {
    /// The length prefix exceeds the limit (nothing beyond the prefix was read).
    TooLarge(u64, usize),
    /// The stream ended inside a frame.
    Truncated,
    Io(std::io::Error),
}

impl std::fmt::Display for FrameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrameError::TooLarge(n, max) => write!(
                f,
                "control message of {} bytes exceeds the limit of {}",
                n, max
            ),
            FrameError::Truncated => write!(f, "control stream ended inside a message"),
            FrameError::Io(e) => write!(f, "control stream: {}", e),
        }
    }
}
impl std::error::Error for FrameError {}

/// Read one frame; Ok(None) on a clean end of stream at a frame boundary. The length is
/// checked against `max` before any payload is read or allocated.
pub async fn read_frame<R: AsyncRead + Unpin>(
    r: &mut R,
    max: usize,
) -> Result<Option<Vec<u8>>, FrameError> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < 4 {
        match r.read(&mut len[got..]).await {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => return Err(FrameError::Truncated),
            Ok(n) => got += n,
            Err(e) => return Err(classify_io(e)),
        }
    }
    let n = u32::from_le_bytes(len) as u64;
    if n > max as u64 {
        return Err(FrameError::TooLarge(n, max));
    }
    let mut buf = vec![0u8; n as usize];
    r.read_exact(&mut buf).await.map_err(classify_io)?;
    Ok(Some(buf))
}

fn classify_io(e: std::io::Error) -> FrameError {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        FrameError::Truncated
    } else {
        FrameError::Io(e)
    }
}

/// Split whole frames off the front of a buffer (synchronous twin of `read_frame`, for the
/// property test and fuzzing): Ok(Some((payload, rest))), Ok(None) if incomplete.
pub fn split_frame(b: &[u8], max: usize) -> Result<Option<(&[u8], &[u8])>> {
    if b.len() < 4 {
        return Ok(None);
    }
    let n = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64;
    if n > max as u64 {
        bail!(
            "control message of {} bytes exceeds the limit of {}",
            n,
            max
        );
    }
    let n = n as usize;
    if b.len() - 4 < n {
        return Ok(None);
    }
    Ok(Some((&b[4..4 + n], &b[4 + n..])))
}

/// Data-stream record header: u32 LE chunk index, then the chunk's own 12-byte header
/// (tag, u32 payload length, u32 CRC), then the payload.
pub const RECORD_HEADER_LEN: usize = 16;

/// Parse a record header; checks the index against the chunk count and the length against
/// `max_payload` so the caller can allocate the payload safely.
pub fn parse_record_header(h: &[u8], chunks: u32, max_payload: u64) -> Result<(u32, [u8; 4], u32)> {
    ensure!(
        h.len() == RECORD_HEADER_LEN,
        "record header has {} bytes",
        h.len()
    );
    let index = u32::from_le_bytes([h[0], h[1], h[2], h[3]]);
    ensure!(
        index < chunks,
        "record for chunk {} but the asset has {} chunks",
        index,
        chunks
    );
    let tag = [h[4], h[5], h[6], h[7]];
    let len = u32::from_le_bytes([h[8], h[9], h[10], h[11]]);
    ensure!(
        (len as u64) <= max_payload && (len as usize) <= snerf_asset::chunk::MAX_CHUNK_LEN,
        "chunk {} claims {} payload bytes (limit {})",
        index,
        len,
        max_payload.min(snerf_asset::chunk::MAX_CHUNK_LEN as u64)
    );
    Ok((index, tag, len))
}

/// Asset names: 1..=255 of [A-Za-z0-9._-], not starting with '.', so a name can never
/// leave the served directory.
pub fn valid_asset_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= MAX_NAME_LEN
        && !s.starts_with('.')
        && s.bytes()
            .all(|c| c.is_ascii_alphanumeric() || c == b'.' || c == b'_' || c == b'-')
}

pub fn to_hex(b: &[u8]) -> String {
    const D: &[u8; 16] = b"0123456789abcdef";
    let mut s = String::with_capacity(b.len() * 2);
    for &x in b {
        s.push(D[(x >> 4) as usize] as char);
        s.push(D[(x & 15) as usize] as char);
    }
    s
}

pub fn from_hex(s: &str) -> Result<Vec<u8>> {
    let s = s.as_bytes();
    ensure!(s.len() % 2 == 0, "odd number of hex digits");
    let v = |c: u8| -> Result<u8> {
        Ok(match c {
            b'0'..=b'9' => c - b'0',
            b'a'..=b'f' => c - b'a' + 10,
            b'A'..=b'F' => c - b'A' + 10,
            _ => bail!("not a hex digit: {:?}", c as char),
        })
    };
    s.chunks_exact(2)
        .map(|p| Ok(v(p[0])? << 4 | v(p[1])?))
        .collect()
}

/// Coalesce sorted-or-not chunk indices into [lo, hi) ranges.
pub fn to_ranges(have: &[bool]) -> Vec<[u32; 2]> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < have.len() {
        if have[i] {
            let lo = i;
            while i < have.len() && have[i] {
                i += 1;
            }
            out.push([lo as u32, i as u32]);
        } else {
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_and_messages_round_trip() {
        let m = ClientMsg::Hello {
            version: 1,
            token: "tok".into(),
            asset: Some("a".into()),
            have: vec![[0, 3]],
            resume_id: None,
            pose: Some(Pose::new([1.0, 2.0, 3.0], [0.0, 0.0, -1.0])),
            colour_of: None,
        };
        let f = encode_frame(&m);
        let (payload, rest) = split_frame(&f, 1024).unwrap().unwrap();
        assert!(rest.is_empty());
        assert_eq!(decode_client_msg(payload).unwrap(), m);
        assert!(split_frame(&f[..f.len() - 1], 1024).unwrap().is_none());
        assert!(split_frame(&f, 3).is_err());
        let p = Pose {
            eye: [1.0, -2.0, 3.5],
            forward: [0.0, 1.0, 0.0],
            time: 2.5,
            fov_deg: 70.0,
        };
        assert_eq!(decode_pose(&encode_pose(42, &p)).unwrap(), (42, p));
        let mut bad = encode_pose(1, &p);
        bad[20..24].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(decode_pose(&bad).is_err());
        let zero = Pose::new([0.0; 3], [0.0; 3]);
        assert!(decode_pose(&encode_pose(1, &zero)).is_err());
        assert_eq!(
            to_ranges(&[true, true, false, true, false, false, true]),
            vec![[0, 2], [3, 4], [6, 7]]
        );
        assert_eq!(
            from_hex(&to_hex(&[0, 1, 0xab, 0xff])).unwrap(),
            vec![0, 1, 0xab, 0xff]
        );
        assert!(
            valid_asset_name("a.b_c-1")
                && !valid_asset_name(".x")
                && !valid_asset_name("a/b")
                && !valid_asset_name("")
        );
    }

    #[tokio::test]
    async fn read_frame_limits() {
        let f = encode_frame(&ClientMsg::List { thumbs: false, watch: false });
        let mut r: &[u8] = &f;
        assert!(read_frame(&mut r, 1024).await.unwrap().is_some());
        assert!(read_frame(&mut r, 1024).await.unwrap().is_none());
        let mut r: &[u8] = &f[..5];
        assert!(matches!(
            read_frame(&mut r, 1024).await,
            Err(FrameError::Truncated)
        ));
        let big = (1u32 << 30).to_le_bytes();
        let mut r: &[u8] = &big;
        assert!(matches!(
            read_frame(&mut r, 1024).await,
            Err(FrameError::TooLarge(..))
        ));
    }
}
