//! What a server allows each client and connection (`Limits`, most with `snerf serve` flags),
//! and the QUIC transport those limits configure for both carriers (native and WebTransport).

use anyhow::{anyhow, bail, Result};
use quinn::VarInt;
use std::sync::Arc;
use std::time::Duration;

/// Server limits (most have CLI flags in `snerf serve`).
#[derive(Clone, Debug)]
pub struct Limits {
    /// Simultaneous authenticated clients (a Hello with a valid token). While all are taken,
    /// new connections are refused at the QUIC level (CONNECTION_REFUSED); one that wins a
    /// race for the last slot is closed with BUSY after its Hello. Connections that have not
    /// authenticated never take a slot (see `max_pending`).
    pub max_clients: usize,
    /// Largest control message accepted (bytes).
    pub max_message: usize,
    /// QUIC idle timeout: a peer silent this long is dropped.
    pub idle_timeout: Duration,
    /// Time from a connection's first packet to a valid Hello (TLS handshake, control stream,
    /// Hello): kept short because unauthenticated connections cost the server resources.
    pub auth_timeout: Duration,
    /// Time from the end of the TLS handshake to Hello. `auth_timeout` applies as well, so
    /// this matters only when set shorter than that.
    pub hello_timeout: Duration,
    /// Unauthenticated connections at a time from one source address (IPv6: one /64). At the
    /// cap a new one closes the oldest of that address (BUSY), so an idle flood from an
    /// address cannot lock out a legitimate client at the same address. Large enough for a
    /// burst of legitimate clients starting at once behind one NAT (each is pending only for
    /// its handshake); an attacker then needs `max_pending / this` addresses to fill the table.
    pub max_pending_per_ip: usize,
    /// Unauthenticated connections at a time, all addresses; at the cap a new one closes the
    /// oldest. From half this, new addresses must first pass a QUIC Retry (prove they receive
    /// our packets), so spoofed source addresses cannot fill the table.
    pub max_pending: usize,
    /// Loaded assets kept in memory, by file size; least recently used dropped first. An
    /// asset larger than this is served without being kept.
    pub cache_bytes: u64,
    /// A client whose streams accept no data for this long is dropped (it stopped reading).
    pub stall_timeout: Duration,
    /// Per-client send budget: bytes buffered for one client, unacknowledged (QUIC send window).
    pub send_budget: u64,
    /// Unidirectional data streams in flight per client.
    pub max_streams: usize,
    /// Target bytes per data stream (several blocks per stream).
    pub batch_bytes: usize,
    /// Congestion controller for the data the server sends.
    pub congestion: Congestion,
    /// After everything is sent and acknowledged, close the connection if the client has not
    /// done so within this time.
    pub linger: Duration,
    /// Per-client pacing of block data, bytes per second (None: as fast as QUIC allows), so
    /// one client cannot take a whole uplink; also how tests stretch a stream in time.
    pub max_rate: Option<f64>,
    /// The web viewer's generated certificate is replaced this often (it is valid 13 days;
    /// browsers accept at most 14 for pinned hashes). Default 12 days.
    pub web_cert_rotate: Duration,
    /// Record each batch of blocks committed to a stream, with the pose it was ordered for,
    /// in `ServerStats::send_log` (what tests check the send order on).
    pub log_sends: bool,
    /// The web page's server (`page.rs`): time allowed for a request head, counted from the
    /// connection's accept (TLS handshake included) or from the end of the previous response
    /// on a kept-alive connection. What stops a client that trickles its header (slowloris)
    /// or opens a connection and says nothing.
    pub page_head_timeout: Duration,
    /// Time allowed to hand one response to the kernel: a client that stops reading is
    /// dropped.
    pub page_write_timeout: Duration,
    /// Page connections at a time from one address (IPv6: one /64); at the cap a new one
    /// closes that address's oldest. A browser opens at most 6 per host; this leaves room for
    /// a few headsets behind one NAT.
    pub page_conns_per_ip: usize,
    /// Page connections at a time, all addresses; at the cap a new one closes the oldest.
    pub page_conns: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_clients: 64,
            max_message: 64 * 1024,
            idle_timeout: Duration::from_secs(30),
            auth_timeout: Duration::from_secs(3),
            hello_timeout: Duration::from_secs(10),
            max_pending_per_ip: 32,
            max_pending: 256,
            cache_bytes: 1 << 30,
            stall_timeout: Duration::from_secs(30),
            send_budget: 8 << 20,
            max_streams: 8,
            batch_bytes: 256 * 1024,
            linger: Duration::from_secs(10),
            congestion: Congestion::Cubic,
            log_sends: false,
            max_rate: None,
            web_cert_rotate: Duration::from_secs(12 * 86400),
            page_head_timeout: Duration::from_secs(5),
            page_write_timeout: Duration::from_secs(10),
            page_conns_per_ip: 16,
            page_conns: 256,
        }
    }
}

/// Congestion control. Cubic (default) is quinn's standard controller and the fastest on
/// clean paths (loopback: ~190 MB/s vs ~75 MB/s with BBR here). BBR keeps throughput under
/// random (e.g. Wi-Fi) loss, where loss-based Cubic collapses: through a 5%-loss, 50 ms RTT
/// relay a 1.6 MiB fetch took ~1.3 s with BBR and ~18 s with Cubic (tests/faults.rs). quinn
/// marks its BBR experimental.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Congestion {
    Bbr,
    Cubic,
}

impl std::str::FromStr for Congestion {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Congestion> {
        match s.to_ascii_lowercase().as_str() {
            "bbr" => Ok(Congestion::Bbr),
            "cubic" => Ok(Congestion::Cubic),
            _ => bail!("congestion controller {:?}: use bbr or cubic", s),
        }
    }
}

pub(crate) fn transport(limits: &Limits) -> Result<quinn::TransportConfig> {
    let mut t = quinn::TransportConfig::default();
    t.max_concurrent_bidi_streams(VarInt::from_u32(1))
        .max_concurrent_uni_streams(VarInt::from_u32(0))
        .stream_receive_window(VarInt::from_u32(
            (limits.max_message as u32).saturating_mul(2).max(64 * 1024),
        ))
        .receive_window(VarInt::from_u32(
            (limits.max_message as u32)
                .saturating_mul(4)
                .max(256 * 1024),
        ))
        .send_window(limits.send_budget.max(64 * 1024))
        .max_idle_timeout(Some(
            limits
                .idle_timeout
                .try_into()
                .map_err(|_| anyhow!("idle timeout too large"))?,
        ))
        .datagram_receive_buffer_size(Some(16 * 1024))
        .datagram_send_buffer_size(16 * 1024);
    match limits.congestion {
        Congestion::Bbr => {
            t.congestion_controller_factory(Arc::new(quinn::congestion::BbrConfig::default()))
        }
        Congestion::Cubic => {
            t.congestion_controller_factory(Arc::new(quinn::congestion::CubicConfig::default()))
        }
    };
    Ok(t)
}

