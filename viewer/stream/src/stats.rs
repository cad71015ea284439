//! The server's counters, readable while it runs (`ServerHandle::stats`). A module of their
//! own so that the admission tables (`pending.rs`) and both transports count without
//! depending on the server.

use crate::proto::Pose;
use std::sync::atomic::AtomicU64;

/// Counters, readable while the server runs.
#[derive(Debug, Default)]
pub struct ServerStats {
    /// Connections whose TLS handshake completed.
    pub connections: AtomicU64,
    /// Refused or closed because every client slot was taken.
    pub refused_busy: AtomicU64,
    /// Authenticated clients now (gauge, at most `max_clients`).
    pub clients: AtomicU64,
    /// Connections not yet authenticated now (gauge, at most `max_pending`).
    pub pending: AtomicU64,
    /// Unauthenticated connections closed to make room for newer ones (per-address or total
    /// pending cap).
    pub pending_evicted: AtomicU64,
    /// QUIC Retry packets sent (address validation while many connections are pending).
    pub retries: AtomicU64,
    pub unauthorized: AtomicU64,
    /// Connections closed for a malformed / oversized / out-of-order message or a timeout.
    pub protocol_errors: AtomicU64,
    pub streams_started: AtomicU64,
    pub streams_completed: AtomicU64,
    /// Record bytes (chunk index + chunk) handed to QUIC, all clients.
    pub bytes_sent: AtomicU64,
    /// Of those, the records of style switches (colour parts, `Hello::colour_of`), and how
    /// many records they were.
    pub colour_bytes_sent: AtomicU64,
    pub colour_records_sent: AtomicU64,
    pub bad_datagrams: AtomicU64,
    pub pose_updates: AtomicU64,
    /// Bytes of asset files held in the cache now (gauge, at most `Limits::cache_bytes`).
    pub cache_bytes: AtomicU64,
    /// Assets dropped from the cache to make room.
    pub cache_evictions: AtomicU64,
    /// Batches of blocks committed to streams, in order, all clients (only with
    /// `Limits::log_sends`).
    pub send_log: std::sync::Mutex<Vec<SentBatch>>,
    /// Times the web viewer's generated certificate was replaced.
    pub cert_rotations: AtomicU64,
    /// The web page's TCP connections now (gauge, at most `Limits::page_conns`).
    pub page_conns: AtomicU64,
    /// Page connections closed to make room (per-address or total cap; see `page.rs`).
    pub page_evicted: AtomicU64,
    /// Page connections closed because a request head did not arrive in
    /// `Limits::page_head_timeout` or a response was not read in `Limits::page_write_timeout`.
    pub page_timeouts: AtomicU64,
}

/// One batch of BLKS chunks (or a colour part's block colours) committed to a data stream, and the latest pose of the client
/// when the batch was chosen (None before any).
#[derive(Clone, Debug)]
pub struct SentBatch {
    pub pose: Option<Pose>,
    /// The chunk index of each record (of a colour part: the chunk each rewrites).
    pub chunks: Vec<u32>,
    /// Their record bytes.
    pub bytes: u64,
    /// A style switch's colour records (`Hello::colour_of`), not the asset's own chunks.
    pub colour: bool,
}

