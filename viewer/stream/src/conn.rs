//! The two carriers of `snerf/1` (PROTOCOL.md): a native QUIC connection (ALPN `snerf/1`)
//! and a WebTransport session over HTTP/3 (the web viewer). Both are quinn connections
//! underneath; WebTransport adds a header to each stream (written or read when the stream
//! is opened or accepted) and a prefix to each datagram. After that the server writes and
//! reads the same bytes on the underlying quinn streams, so the session logic in
//! `server.rs` is one code path for both.

use bytes::Bytes;

#[derive(Clone)]
pub(crate) enum Conn {
    Quic(quinn::Connection),
    Web(wtransport::Connection),
}

/// A stream the server writes (a data stream or the control stream's send half).
pub(crate) enum Send {
    Quic(quinn::SendStream),
    Web(wtransport::SendStream),
}

/// The control stream's receive half.
pub(crate) enum Recv {
    Quic(quinn::RecvStream),
    Web(wtransport::RecvStream),
}

impl Send {
    pub fn quic(&mut self) -> &mut quinn::SendStream {
        match self {
            Send::Quic(s) => s,
            Send::Web(s) => s.quic_stream_mut(),
        }
    }
}

impl Recv {
    pub fn quic(&mut self) -> &mut quinn::RecvStream {
        match self {
            Recv::Quic(s) => s,
            Recv::Web(s) => s.quic_stream_mut(),
        }
    }
}

impl Conn {
    /// The QUIC connection underneath (closing, congestion state, addresses).
    pub fn quic(&self) -> &quinn::Connection {
        match self {
            Conn::Quic(c) => c,
            Conn::Web(w) => w.quic_connection(),
        }
    }

    /// The client's control stream. Err: the connection is gone.
    pub async fn accept_bi(&self) -> Result<(Send, Recv), ()> {
        match self {
            Conn::Quic(c) => c
                .accept_bi()
                .await
                .map(|(s, r)| (Send::Quic(s), Recv::Quic(r)))
                .map_err(|_| ()),
            Conn::Web(w) => w
                .accept_bi()
                .await
                .map(|(s, r)| (Send::Web(s), Recv::Web(r)))
                .map_err(|_| ()),
        }
    }

    /// A new server-initiated unidirectional stream (waits for stream credit).
    pub async fn open_uni(&self) -> Result<Send, String> {
        match self {
            Conn::Quic(c) => c.open_uni().await.map(Send::Quic).map_err(|e| e.to_string()),
            Conn::Web(w) => {
                let opening = w.open_uni().await.map_err(|e| e.to_string())?;
                opening.await.map(Send::Web).map_err(|e| e.to_string())
            }
        }
    }

    /// The next datagram's payload; None once the connection is gone.
    pub async fn read_datagram(&self) -> Option<Bytes> {
        match self {
            Conn::Quic(c) => c.read_datagram().await.ok(),
            Conn::Web(w) => w.receive_datagram().await.ok().map(|d| d.payload()),
        }
    }
}
