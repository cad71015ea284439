//! Client side: connect with a pinned fingerprint, say Hello (with what we already have),
//! receive chunk records on the server's unidirectional streams, and either write a complete
//! verified file (`fetch`) or feed a live `Assembler` (`LiveAsset`).

use anyhow::{anyhow, bail, ensure, Context, Result};
use quinn::{Connection, ConnectionError, Endpoint, RecvStream, SendStream, VarInt};
use sha2::{Digest, Sha256};
use snerf_asset::chunk::{parse_chunk_at, CHUNK_HEADER_LEN, PREAMBLE_LEN, TAG_HEAD};
use snerf_asset::{Assembler, Asset};
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

use crate::proto::{
    code, decode_server_msg, encode_frame, from_hex, parse_record_header, read_frame, to_hex,
    to_ranges, AssetInfo, ClientMsg, ListEntry, Pose, ServerMsg, PROTOCOL_VERSION,
    RECORD_HEADER_LEN,
};
use crate::tls::{self, PinVerifier};
use crate::url::{parse_url, resolve};

/// Client tuning; the defaults suit real networks.
#[derive(Clone, Debug)]
pub struct ClientOptions {
    pub connect_timeout: Duration,
    pub idle_timeout: Duration,
    pub keep_alive: Duration,
    /// Per-stream and per-connection receive windows (bytes the server may have in flight).
    pub stream_window: u32,
    pub connection_window: u32,
    /// Concurrent data streams the server may open.
    pub max_streams: u32,
    /// Initial pose (sent in Hello so the very first blocks are the right ones).
    pub pose: Option<Pose>,
    /// Largest control message accepted from the server.
    pub max_message: usize,
    /// Testing aid: drop the connection after this many record bytes (simulates a cut).
    pub abort_after_bytes: Option<u64>,
}

impl Default for ClientOptions {
    fn default() -> ClientOptions {
        ClientOptions {
            connect_timeout: Duration::from_secs(15),
            idle_timeout: Duration::from_secs(30),
            keep_alive: Duration::from_secs(5),
            stream_window: 4 << 20,
            connection_window: 32 << 20,
            max_streams: 64,
            pose: None,
            max_message: 4 << 20,
            abort_after_bytes: None,
        }
    }
}

/// What a fetch did.
#[derive(Clone, Debug, Default)]
pub struct FetchStats {
    pub size: u64,
    pub chunks: u32,
    /// The server honoured our `have` list.
    pub resumed: bool,
    /// Chunks / chunk bytes that came from the `.part` file of an earlier attempt.
    pub chunks_already_had: u32,
    pub bytes_already_had: u64,
    /// Records received on this connection and their bytes (chunk + 4-byte index).
    pub chunks_received: u32,
    pub bytes_received: u64,
    /// UDP payload bytes received on this connection (QUIC overhead included).
    pub udp_bytes_received: u64,
    /// Connect start to last chunk received.
    pub transfer: Duration,
    /// Connect start to header + grids + MLP present.
    pub time_to_renderable: Option<Duration>,
    /// Everything, including writing and re-verifying the file.
    pub elapsed: Duration,
}

fn transport(opts: &ClientOptions) -> Result<quinn::TransportConfig> {
    let mut t = quinn::TransportConfig::default();
    t.max_concurrent_bidi_streams(VarInt::from_u32(0))
        .max_concurrent_uni_streams(VarInt::from_u32(opts.max_streams))
        .stream_receive_window(VarInt::from_u32(opts.stream_window))
        .receive_window(VarInt::from_u32(opts.connection_window))
        .max_idle_timeout(Some(
            opts.idle_timeout
                .try_into()
                .map_err(|_| anyhow!("idle timeout too large"))?,
        ))
        .keep_alive_interval(Some(opts.keep_alive))
        .datagram_receive_buffer_size(Some(16 * 1024))
        .datagram_send_buffer_size(16 * 1024);
    Ok(t)
}

/// An open, authenticated control session.
pub struct Session {
    pub endpoint: Endpoint,
    pub conn: Connection,
    pub send: SendStream,
    pub recv: RecvStream,
    pub asset: Option<AssetInfo>,
    pub resumed: bool,
    pub sending_chunks: u32,
    pub sending_bytes: u64,
    /// The welcome answered a style switch (`ClientMsg::Hello::colour_of`).
    pub colour_only: bool,
    pub started: Instant,
    verifier: Arc<PinVerifier>,
    max_message: usize,
}

/// Turn a connection error into a message a person can act on.
pub fn explain(e: &ConnectionError, verifier: Option<&PinVerifier>) -> anyhow::Error {
    if let Some(m) = verifier.and_then(|v| v.mismatch_message()) {
        return anyhow!("refusing the server: {}", m);
    }
    match e {
        ConnectionError::ApplicationClosed(c) => {
            let code = c.error_code.into_inner();
            anyhow!(
                "server closed the connection: {} (code {}): {}",
                code::name(code),
                code,
                String::from_utf8_lossy(&c.reason)
            )
        }
        ConnectionError::ConnectionClosed(c)
            if c.error_code == quinn::TransportErrorCode::CONNECTION_REFUSED =>
        {
            anyhow!("server refused the connection (at its client limit?)")
        }
        ConnectionError::ConnectionClosed(c) => anyhow!("connection closed by the server: {}", c),
        ConnectionError::TransportError(t) => anyhow!("connection failed: {}", t),
        ConnectionError::TimedOut => anyhow!("connection timed out (server unreachable or silent)"),
        other => anyhow!("connection failed: {}", other),
    }
}

impl Session {
    pub fn explain(&self, e: &ConnectionError) -> anyhow::Error {
        explain(e, Some(&self.verifier))
    }

    /// Why the connection ended, if it has.
    pub fn close_error(&self) -> Option<anyhow::Error> {
        self.conn.close_reason().map(|e| self.explain(&e))
    }

    pub(crate) async fn read_msg(&mut self) -> Result<ServerMsg> {
        match read_frame(&mut self.recv, self.max_message).await {
            Ok(Some(b)) => decode_server_msg(&b),
            Ok(None) => Err(self
                .close_error()
                .unwrap_or_else(|| anyhow!("server closed the control stream"))),
            Err(e) => Err(self.close_error().unwrap_or_else(|| anyhow!("{}", e))),
        }
    }

    /// Ask for the server's asset list.
    pub async fn list(&mut self) -> Result<Vec<ListEntry>> {
        self.send
            .write_all(&encode_frame(&ClientMsg::List { thumbs: false, watch: false }))
            .await
            .map_err(|e| anyhow!("control stream: {}", e))?;
        match self.read_msg().await? {
            ServerMsg::Listing { assets } => Ok(assets),
            other => bail!("unexpected server message {:?}", other),
        }
    }

    pub fn close(&self) {
        self.conn.close(VarInt::from_u32(code::DONE), b"done");
    }
}

/// Open a QUIC connection to `addr` that accepts only the pinned certificate (no Hello
/// yet). `open_session` builds on it; tests use it to speak raw protocol.
pub async fn connect_raw(
    addr: SocketAddr,
    pin: &str,
    opts: &ClientOptions,
) -> Result<(Endpoint, Connection, Arc<PinVerifier>)> {
    let pin = tls::parse_pin(pin)?;
    let verifier = Arc::new(PinVerifier::new(pin));
    let mut cc = quinn::ClientConfig::new(Arc::new(tls::client_crypto(verifier.clone())?));
    cc.transport_config(Arc::new(transport(opts)?));
    let bind: SocketAddr = if addr.is_ipv6() {
        "[::]:0".parse()?
    } else {
        "0.0.0.0:0".parse()?
    };
    let socket = crate::proto::udp_socket(bind).context("cannot open a UDP socket")?;
    let runtime = quinn::default_runtime().ok_or_else(|| anyhow!("no async runtime"))?;
    let mut endpoint = Endpoint::new(quinn::EndpointConfig::default(), None, socket, runtime)
        .context("cannot open a UDP socket")?;
    endpoint.set_default_client_config(cc);
    let connecting = endpoint
        .connect(addr, "snerf")
        .map_err(|e| anyhow!("cannot connect to {}: {}", addr, e))?;
    let conn = match tokio::time::timeout(opts.connect_timeout, connecting).await {
        Err(_) => bail!("no answer from {} within {:?}", addr, opts.connect_timeout),
        Ok(Err(e)) => {
            return Err(explain(&e, Some(&verifier)).context(format!("connecting to {}", addr)))
        }
        Ok(Ok(c)) => c,
    };
    Ok((endpoint, conn, verifier))
}

/// Connect to `addr`, verify the pin, send Hello and read Welcome.
pub async fn open_session(
    addr: SocketAddr,
    pin: &str,
    hello: ClientMsg,
    opts: &ClientOptions,
) -> Result<Session> {
    let started = Instant::now();
    let (endpoint, conn, verifier) = connect_raw(addr, pin, opts).await?;
    let (mut send, recv) = conn
        .open_bi()
        .await
        .map_err(|e| explain(&e, Some(&verifier)))?;
    send.write_all(&encode_frame(&hello))
        .await
        .map_err(|e| match conn.close_reason() {
            Some(c) => explain(&c, Some(&verifier)),
            None => anyhow!("control stream: {}", e),
        })?;
    let mut s = Session {
        endpoint,
        conn,
        send,
        recv,
        asset: None,
        resumed: false,
        sending_chunks: 0,
        sending_bytes: 0,
        colour_only: false,
        started,
        verifier,
        max_message: opts.max_message,
    };
    let welcome = tokio::time::timeout(opts.connect_timeout, s.read_msg())
        .await
        .map_err(|_| {
            anyhow!(
                "server at {} sent no Welcome within {:?}",
                addr,
                opts.connect_timeout
            )
        })??;
    match welcome {
        ServerMsg::Welcome {
            version,
            asset,
            resumed,
            sending_chunks,
            sending_bytes,
            colour_only,
        } => {
            ensure!(
                version == PROTOCOL_VERSION,
                "server speaks protocol version {}",
                version
            );
            s.asset = asset;
            s.resumed = resumed;
            s.sending_chunks = sending_chunks;
            s.sending_bytes = sending_bytes;
            s.colour_only = colour_only;
        }
        other => bail!("server sent {:?} instead of Welcome", other),
    }
    Ok(s)
}

/// List the assets of a server (`url` = quic://HOST:PORT/ or any asset URL of it).
pub async fn list(url: &str, pin: &str, token: &str) -> Result<Vec<ListEntry>> {
    let (hp, _) = parse_url(url)?;
    let addr = resolve(&hp)?;
    let hello = ClientMsg::Hello {
        version: PROTOCOL_VERSION,
        token: token.to_string(),
        asset: None,
        have: vec![],
        resume_id: None,
        pose: None,
        colour_of: None,
    };
    let mut s = open_session(addr, pin, hello, &ClientOptions::default()).await?;
    let l = s.list().await;
    s.close();
    l
}

/// One chunk as received: file chunk index + the encoded chunk (header + payload).
pub struct Record {
    pub index: u32,
    pub chunk: Vec<u8>,
}

/// Accept data streams and turn them into records until the connection ends. Returns the
/// connection's end as an error (or Ok if closed locally).
pub async fn receive(
    conn: Connection,
    info: AssetInfo,
    tx: mpsc::Sender<Record>,
    bytes: Arc<AtomicU64>,
    abort_after: Option<u64>,
) -> std::result::Result<(), ConnectionError> {
    loop {
        let s = conn.accept_uni().await?;
        let (tx, bytes, info, conn2) = (tx.clone(), bytes.clone(), info.clone(), conn.clone());
        tokio::spawn(async move {
            if let Err(e) = read_records(s, &info, &tx, &bytes, abort_after, &conn2).await {
                if conn2.close_reason().is_none() {
                    conn2.close(
                        VarInt::from_u32(code::CLIENT_REJECT),
                        format!("{:#}", e).as_bytes(),
                    );
                }
            }
        });
    }
}

async fn read_records(
    mut s: RecvStream,
    info: &AssetInfo,
    tx: &mpsc::Sender<Record>,
    bytes: &AtomicU64,
    abort_after: Option<u64>,
    conn: &Connection,
) -> Result<()> {
    loop {
        let mut h = [0u8; RECORD_HEADER_LEN];
        match s.read_exact(&mut h).await {
            Ok(()) => {}
            Err(quinn::ReadExactError::FinishedEarly(0)) => return Ok(()),
            Err(quinn::ReadExactError::FinishedEarly(n)) => {
                bail!("data stream ended inside a record header ({} bytes)", n)
            }
            Err(quinn::ReadExactError::ReadError(_)) => return Ok(()), // connection ending: reported elsewhere
        }
        let (index, _tag, len) = parse_record_header(&h, info.chunks, info.size)?;
        let mut chunk = vec![0u8; CHUNK_HEADER_LEN + len as usize];
        chunk[..CHUNK_HEADER_LEN].copy_from_slice(&h[4..]);
        match s.read_exact(&mut chunk[CHUNK_HEADER_LEN..]).await {
            Ok(()) => {}
            Err(quinn::ReadExactError::FinishedEarly(_)) => {
                bail!("data stream ended inside chunk {}", index)
            }
            Err(quinn::ReadExactError::ReadError(_)) => return Ok(()),
        }
        let total =
            bytes.fetch_add(4 + chunk.len() as u64, Ordering::Relaxed) + 4 + chunk.len() as u64;
        if tx.send(Record { index, chunk }).await.is_err() {
            return Ok(());
        }
        if abort_after.is_some_and(|a| total >= a) {
            conn.close(VarInt::from_u32(code::DONE), b"client aborted (test cut)");
            return Ok(());
        }
    }
}

/// Chunks collected so far, whatever their order, validated with an `Assembler`.
pub struct Collector {
    pub info: AssetInfo,
    pub preamble: [u8; PREAMBLE_LEN],
    pub asm: Option<Assembler>,
    pending: Vec<(u32, Vec<u8>)>,
    pub have: Vec<bool>,
    pub have_count: u32,
    pub have_bytes: u64,
    pub renderable: bool,
}

/// What accepting a chunk changed.
pub struct Accepted {
    pub new: bool,
    /// Block indices that became present.
    pub blocks: Vec<u32>,
    /// This chunk made the asset renderable (header, MLP and every grid present).
    pub became_renderable: bool,
}

impl Collector {
    pub fn new(info: AssetInfo) -> Result<Collector> {
        let p = from_hex(&info.preamble)?;
        ensure!(p.len() == PREAMBLE_LEN, "bad preamble length");
        snerf_asset::chunk::check_preamble(&p)?;
        let mut preamble = [0u8; PREAMBLE_LEN];
        preamble.copy_from_slice(&p);
        let n = info.chunks as usize;
        Ok(Collector {
            info,
            preamble,
            asm: None,
            pending: Vec::new(),
            have: vec![false; n],
            have_count: 0,
            have_bytes: 0,
            renderable: false,
        })
    }

    pub fn is_complete(&self) -> bool {
        self.have_count == self.info.chunks
    }

    /// Check framing + CRC, feed the assembler. Errors mean the server sent bad data.
    pub fn accept(&mut self, index: u32, chunk: Vec<u8>) -> Result<(Accepted, Option<Vec<u8>>)> {
        let i = index as usize;
        ensure!(i < self.have.len(), "chunk {} out of range", index);
        if self.have[i] {
            return Ok((
                Accepted {
                    new: false,
                    blocks: vec![],
                    became_renderable: false,
                },
                None,
            ));
        }
        let c = parse_chunk_at(&chunk, 0, i)?;
        ensure!(
            c.range.end == chunk.len(),
            "chunk {} has trailing bytes",
            index
        );
        ensure!(
            (c.tag == TAG_HEAD) == (index == 0),
            "chunk {} is {}, HEAD must be chunk 0",
            index,
            snerf_asset::chunk::tag_name(&c.tag)
        );
        let mut blocks = Vec::new();
        if index == 0 {
            let mut first = Vec::with_capacity(PREAMBLE_LEN + chunk.len());
            first.extend_from_slice(&self.preamble);
            first.extend_from_slice(&chunk);
            let mut asm = Assembler::new(&first)?;
            ensure!(
                asm.header().atlas_blocks == self.info.atlas_blocks,
                "HEAD says {} blocks, Welcome said {}",
                asm.header().atlas_blocks,
                self.info.atlas_blocks
            );
            for (_, p) in std::mem::take(&mut self.pending) {
                push(&mut asm, &p, &mut blocks)?;
            }
            self.asm = Some(asm);
        } else if let Some(asm) = self.asm.as_mut() {
            push(asm, &chunk, &mut blocks)?;
        } else {
            self.pending.push((index, chunk.clone()));
        }
        self.have[i] = true;
        self.have_count += 1;
        self.have_bytes += chunk.len() as u64;
        let mut became = false;
        if !self.renderable {
            if let Some(a) = &self.asm {
                if a.has_mlp() && a.missing_frames().is_empty() {
                    self.renderable = true;
                    became = true;
                }
            }
        }
        Ok((
            Accepted {
                new: true,
                blocks,
                became_renderable: became,
            },
            Some(chunk),
        ))
    }
}

/// Push an encoded chunk whose framing and CRC were already checked.
fn push(asm: &mut Assembler, chunk: &[u8], blocks: &mut Vec<u32>) -> Result<()> {
    let tag = [chunk[0], chunk[1], chunk[2], chunk[3]];
    asm.push(tag, &chunk[CHUNK_HEADER_LEN..])?;
    if chunk[..4] == snerf_asset::chunk::TAG_BLKS {
        let p = &chunk[CHUNK_HEADER_LEN..];
        let first = u32::from_le_bytes([p[0], p[1], p[2], p[3]]);
        let count = u32::from_le_bytes([p[4], p[5], p[6], p[7]]);
        blocks.extend(first..first + count);
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// fetch: the .part log and the final file

const PART_MAGIC: &[u8; 8] = b"SNERFPRT";
const PART_HEADER_LEN: u64 = 64;

/// `<out>.part`: where an interrupted fetch keeps what it received.
pub fn part_path(out: &Path) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".part");
    PathBuf::from(s)
}

/// The resume log: header (magic, version, chunk count, sha256, preamble), then records
/// (u32 index + encoded chunk) in arrival order. A torn tail is cut off on load.
struct PartLog {
    path: PathBuf,
    file: BufWriter<std::fs::File>,
    pos: u64,
    offsets: Vec<Option<(u64, u32)>>,
}

struct Loaded {
    sha: String,
    collector: Collector,
    log: PartLog,
}

fn part_header(info: &AssetInfo, sha: &[u8], preamble: &[u8]) -> Vec<u8> {
    let mut h = Vec::with_capacity(PART_HEADER_LEN as usize);
    h.extend_from_slice(PART_MAGIC);
    h.extend_from_slice(&1u32.to_le_bytes());
    h.extend_from_slice(&info.chunks.to_le_bytes());
    h.extend_from_slice(sha);
    h.extend_from_slice(preamble);
    h
}

impl PartLog {
    fn create(path: &Path, info: &AssetInfo) -> Result<PartLog> {
        let sha = from_hex(&info.sha256)?;
        let pre = from_hex(&info.preamble)?;
        let mut f = std::fs::File::create(path)
            .with_context(|| format!("{}: cannot create", path.display()))?;
        f.write_all(&part_header(info, &sha, &pre))
            .with_context(|| format!("{}: cannot write", path.display()))?;
        Ok(PartLog {
            path: path.to_path_buf(),
            file: BufWriter::with_capacity(1 << 20, f),
            pos: PART_HEADER_LEN,
            offsets: vec![None; info.chunks as usize],
        })
    }

    fn append(&mut self, index: u32, chunk: &[u8]) -> Result<()> {
        self.file
            .write_all(&index.to_le_bytes())
            .and_then(|_| self.file.write_all(chunk))
            .with_context(|| format!("{}: cannot write", self.path.display()))?;
        self.offsets[index as usize] = Some((self.pos + 4, chunk.len() as u32));
        self.pos += 4 + chunk.len() as u64;
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        self.file
            .flush()
            .with_context(|| format!("{}: cannot write", self.path.display()))
    }

    /// Load an existing log. Ok(None) if absent or unusable (it will be recreated).
    fn load(path: &Path) -> Result<Option<Loaded>> {
        let Ok(f) = std::fs::File::open(path) else {
            return Ok(None);
        };
        let mut r = BufReader::with_capacity(1 << 20, f);
        let mut h = [0u8; PART_HEADER_LEN as usize];
        if r.read_exact(&mut h).is_err() || &h[..8] != PART_MAGIC || h[8..12] != 1u32.to_le_bytes()
        {
            return Ok(None);
        }
        let chunks = u32::from_le_bytes([h[12], h[13], h[14], h[15]]);
        let sha = to_hex(&h[16..48]);
        let info = AssetInfo {
            name: String::new(),
            size: u64::MAX >> 24,
            chunks,
            sha256: sha.clone(),
            preamble: to_hex(&h[48..64]),
            atlas_blocks: 0,
            frames: 0,
            geometry: None,
        };
        let Ok(mut collector) = Collector::new(info.clone()) else {
            return Ok(None);
        };
        if !(2..=1 << 28).contains(&chunks) {
            return Ok(None);
        }
        let mut offsets = vec![None; chunks as usize];
        let mut pos = PART_HEADER_LEN;
        loop {
            let mut rh = [0u8; RECORD_HEADER_LEN];
            if r.read_exact(&mut rh).is_err() {
                break;
            }
            let Ok((index, _, len)) =
                parse_record_header(&rh, chunks, snerf_asset::chunk::MAX_CHUNK_LEN as u64)
            else {
                break;
            };
            let mut chunk = vec![0u8; CHUNK_HEADER_LEN + len as usize];
            chunk[..CHUNK_HEADER_LEN].copy_from_slice(&rh[4..]);
            if r.read_exact(&mut chunk[CHUNK_HEADER_LEN..]).is_err() {
                break;
            }
            // Atlas count is unknown until HEAD: skip that cross-check while replaying.
            if index == 0 {
                if let Ok(hd) = snerf_asset::parse_head(&chunk[CHUNK_HEADER_LEN..]) {
                    collector.info.atlas_blocks = hd.atlas_blocks;
                }
            }
            match collector.accept(index, chunk) {
                Ok((a, _)) if a.new => {
                    offsets[index as usize] =
                        Some((pos + 4, (CHUNK_HEADER_LEN + len as usize) as u32));
                }
                Ok(_) => {}
                Err(_) => break,
            }
            pos += (RECORD_HEADER_LEN + len as usize) as u64;
        }
        drop(r);
        // Cut a torn or bad tail, then append after the good records.
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .with_context(|| format!("{}: cannot open", path.display()))?;
        f.set_len(pos)
            .with_context(|| format!("{}: cannot truncate", path.display()))?;
        let mut f = f;
        f.seek(SeekFrom::Start(pos))?;
        let log = PartLog {
            path: path.to_path_buf(),
            file: BufWriter::with_capacity(1 << 20, f),
            pos,
            offsets,
        };
        Ok(Some(Loaded {
            sha,
            collector,
            log,
        }))
    }

    /// Write the complete file: preamble + chunks in index order, to a temp file beside
    /// `out`, checking the SHA-256, fsync, rename.
    fn assemble(&mut self, preamble: &[u8], out: &Path, sha: &str) -> Result<()> {
        self.flush()?;
        let mut src = std::fs::File::open(&self.path)
            .with_context(|| format!("{}: cannot read", self.path.display()))?;
        let name = out
            .file_name()
            .ok_or_else(|| anyhow!("{}: not a file path", out.display()))?;
        let dir = match out.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let tmp = dir.join(format!(
            ".{}.{}.tmp",
            name.to_string_lossy(),
            std::process::id()
        ));
        let r = (|| -> Result<()> {
            let mut o = BufWriter::with_capacity(1 << 20, std::fs::File::create(&tmp)?);
            let mut hasher = Sha256::new();
            o.write_all(preamble)?;
            hasher.update(preamble);
            let mut buf = Vec::new();
            for (i, off) in self.offsets.iter().enumerate() {
                let (off, len) = off.ok_or_else(|| anyhow!("chunk {} missing", i))?;
                buf.resize(len as usize, 0);
                src.seek(SeekFrom::Start(off))?;
                src.read_exact(&mut buf)?;
                o.write_all(&buf)?;
                hasher.update(&buf);
            }
            let got = to_hex(&hasher.finalize());
            ensure!(
                got == sha,
                "assembled file has SHA-256 {} but the server's file has {}",
                got,
                sha
            );
            let f = o.into_inner().map_err(|e| anyhow!("{}", e.error()))?;
            f.sync_all()?;
            drop(f);
            std::fs::rename(&tmp, out)?;
            if let Ok(d) = std::fs::File::open(&dir) {
                let _ = d.sync_all();
            }
            Ok(())
        })();
        if r.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        r.with_context(|| format!("{}: cannot write the downloaded asset", out.display()))
    }
}

/// Download `quic://HOST:PORT/ASSET` to `out`, verifying the server by `pin`. Resumes from
/// `<out>.part` if an earlier attempt left one. The file appears atomically and complete or
/// not at all; it is re-read with `Asset::read` before returning.
pub async fn fetch(url: &str, pin: &str, token: &str, out: &Path) -> Result<FetchStats> {
    fetch_with(url, pin, token, out, &ClientOptions::default()).await
}

pub async fn fetch_with(
    url: &str,
    pin: &str,
    token: &str,
    out: &Path,
    opts: &ClientOptions,
) -> Result<FetchStats> {
    let t0 = Instant::now();
    let (hp, asset) = parse_url(url)?;
    let addr = resolve(&hp)?;
    let part = part_path(out);
    let part2 = part.clone();
    let loaded = tokio::task::spawn_blocking(move || PartLog::load(&part2))
        .await
        .map_err(|e| anyhow!("{}", e))??;
    let (have, resume_id) = match &loaded {
        Some(l) => (to_ranges(&l.collector.have), Some(l.sha.clone())),
        None => (vec![], None),
    };
    let hello = ClientMsg::Hello {
        version: PROTOCOL_VERSION,
        token: token.to_string(),
        asset: Some(asset.clone()),
        have,
        resume_id,
        pose: opts.pose,
        colour_of: None,
    };
    let session = open_session(addr, pin, hello, opts).await?;
    let info = session
        .asset
        .clone()
        .ok_or_else(|| anyhow!("server sent no asset information"))?;
    // Keep the earlier attempt's chunks only if they are of this very file.
    let (mut collector, mut log) = match loaded {
        Some(l)
            if session.resumed
                && l.sha == info.sha256
                && l.collector.info.chunks == info.chunks =>
        {
            let mut c = l.collector;
            c.info = info.clone();
            (c, l.log)
        }
        _ => (
            Collector::new(info.clone())?,
            PartLog::create(&part, &info)?,
        ),
    };
    let mut stats = FetchStats {
        size: info.size,
        chunks: info.chunks,
        resumed: session.resumed,
        chunks_already_had: collector.have_count,
        bytes_already_had: collector.have_bytes,
        ..Default::default()
    };
    let bytes = Arc::new(AtomicU64::new(0));
    let (tx, mut rx) = mpsc::channel::<Record>(256);
    let conn = session.conn.clone();
    let recv_task = tokio::spawn(receive(
        conn.clone(),
        info.clone(),
        tx,
        bytes.clone(),
        opts.abort_after_bytes,
    ));
    // The sink runs on a blocking thread: CRC, assembly and the .part writes.
    let started = session.started;
    let sink = tokio::task::spawn_blocking(
        move || -> (Result<(u32, Option<Duration>)>, Collector, PartLog) {
            let mut received = 0u32;
            let mut ttr = None;
            let r = (|| -> Result<()> {
                while !collector.is_complete() {
                    let Some(rec) = rx.blocking_recv() else { break };
                    let (a, chunk) = collector
                        .accept(rec.index, rec.chunk)
                        .map_err(|e| anyhow!("server sent bad data: {:#}", e))?;
                    if a.new {
                        received += 1;
                        log.append(rec.index, chunk.as_deref().unwrap_or(&[]))?;
                    }
                    if a.became_renderable {
                        ttr = Some(started.elapsed());
                    }
                }
                log.flush()
            })();
            let _ = log.flush();
            (r.map(|_| (received, ttr)), collector, log)
        },
    );
    let (res, collector, mut log) = sink
        .await
        .map_err(|e| anyhow!("fetch sink failed: {}", e))?;
    stats.transfer = t0.elapsed();
    stats.bytes_received = bytes.load(Ordering::Relaxed);
    stats.udp_bytes_received = conn.stats().udp_rx.bytes;
    let ok = res.as_ref().is_ok() && collector.is_complete();
    if let Err(e) = &res {
        conn.close(
            VarInt::from_u32(code::CLIENT_REJECT),
            format!("{:#}", e).as_bytes(),
        );
    } else if ok {
        session.close();
    }
    recv_task.abort();
    let why = conn.close_reason().map(|e| session.explain(&e));
    let (received, ttr) = match res {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_file(&part); // bad data: do not resume from it
            return Err(e.context(format!("fetching {}", url)));
        }
    };
    stats.chunks_received = received;
    stats.time_to_renderable = ttr;
    if !ok {
        let e = why.unwrap_or_else(|| anyhow!("connection ended"));
        bail!(
            "download of {} interrupted after {} of {} chunks ({}); {} keeps them: run the same fetch again to resume",
            url,
            collector.have_count,
            info.chunks,
            e,
            part.display()
        );
    }
    let (pre, out2, sha) = (collector.preamble, out.to_path_buf(), info.sha256.clone());
    tokio::task::spawn_blocking(move || -> Result<()> {
        log.assemble(&pre, &out2, &sha)?;
        Asset::read(&out2).map_err(|e| anyhow!("downloaded file does not verify: {:#}", e))?;
        Ok(())
    })
    .await
    .map_err(|e| anyhow!("{}", e))??;
    let _ = std::fs::remove_file(&part);
    session.endpoint.wait_idle().await;
    stats.elapsed = t0.elapsed();
    Ok(stats)
}

/// Blocking `fetch` on a private runtime.
/// `list` on a runtime of its own, for synchronous callers.
pub fn list_blocking(url: &str, pin: &str, token: &str) -> Result<Vec<ListEntry>> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?
        .block_on(list(url, pin, token))
}

pub fn fetch_blocking(url: &str, pin: &str, token: &str, out: &Path) -> Result<FetchStats> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?
        .block_on(fetch(url, pin, token, out))
}
