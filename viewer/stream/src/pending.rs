//! Connections that have not authenticated yet ("pending": handshaking, or waiting for a
//! Hello with a valid token). They hold no client slot — only authenticated clients count
//! against `Limits::max_clients`, so an attacker without the token cannot lock real clients
//! out by opening idle connections — but each costs a handshake, a task and memory until
//! `Limits::auth_timeout`. This table bounds them per source address and in total.
//!
//! At a cap the server closes the **oldest** pending connection (of that address, or of all)
//! rather than refusing the newcomer. An attacker who keeps opening idle connections then
//! only displaces a legitimate client if it opens a cap's worth of new ones during the few
//! round trips that client needs to authenticate; refusing newcomers instead would lock
//! legitimate clients out for as long as the attacker keeps the table full, which it can do
//! at a rate of only one connection per `auth_timeout / cap`.

use std::collections::{HashMap, VecDeque};
use std::net::IpAddr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use tokio::sync::oneshot;

use crate::stats::ServerStats;

/// Why a pending connection was closed to make room.
pub(crate) type Evicted = &'static str;

struct Entry {
    id: u64,
    source: IpAddr,
    evict: oneshot::Sender<Evicted>,
}

#[derive(Default)]
struct Inner {
    /// Oldest first.
    order: VecDeque<Entry>,
    per_source: HashMap<IpAddr, usize>,
    next_id: u64,
}

pub(crate) struct PendingTable {
    inner: Mutex<Inner>,
    max_per_source: usize,
    max_total: usize,
    stats: Arc<ServerStats>,
    counted: Counted,
}

/// Which counters of `ServerStats` a table keeps: the same rule bounds two kinds of
/// connection that have not earned their place yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Counted {
    /// QUIC and WebTransport connections before a valid Hello: `pending`, `pending_evicted`.
    Handshakes,
    /// The web page's TCP connections (`page.rs`): `page_conns`, `page_evicted`.
    Pages,
}

/// One pending connection's place in the table; dropping it (authenticated, or gone) frees
/// the place.
pub(crate) struct Pending {
    table: Arc<PendingTable>,
    id: u64,
    evicted: oneshot::Receiver<Evicted>,
}

/// The address a per-source cap applies to. IPv4-mapped IPv6 counts as its IPv4 address;
/// IPv6 is grouped by /64, since one host commonly has a whole /64 to pick addresses from.
pub(crate) fn source_key(ip: IpAddr) -> IpAddr {
    match ip.to_canonical() {
        IpAddr::V6(v6) => {
            let mut s = v6.segments();
            s[4..].fill(0);
            IpAddr::V6(s.into())
        }
        v4 => v4,
    }
}

impl PendingTable {
    pub fn new(max_per_source: usize, max_total: usize, stats: Arc<ServerStats>, counted: Counted) -> PendingTable {
        PendingTable {
            inner: Mutex::new(Inner::default()),
            max_per_source: max_per_source.max(1),
            max_total: max_total.max(1),
            stats,
            counted,
        }
    }

    fn gauge(&self) -> &std::sync::atomic::AtomicU64 {
        match self.counted {
            Counted::Handshakes => &self.stats.pending,
            Counted::Pages => &self.stats.page_conns,
        }
    }

    fn evictions(&self) -> &std::sync::atomic::AtomicU64 {
        match self.counted {
            Counted::Handshakes => &self.stats.pending_evicted,
            Counted::Pages => &self.stats.page_evicted,
        }
    }

    /// Pending connections now.
    pub fn len(&self) -> usize {
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner).order.len()
    }

    pub fn max_total(&self) -> usize {
        self.max_total
    }

    /// Enter a new connection from `ip`, first closing the oldest pending one of the same
    /// source if that source is at its cap, and the oldest of all if the table is full.
    pub fn admit(self: &Arc<Self>, ip: IpAddr) -> Pending {
        let source = source_key(ip);
        let mut t = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if t.per_source.get(&source).copied().unwrap_or(0) >= self.max_per_source {
            let i = t.order.iter().position(|e| e.source == source);
            self.evict(
                &mut t,
                i,
                "too many unauthenticated connections from your address",
            );
        }
        if t.order.len() >= self.max_total {
            self.evict(&mut t, Some(0), "too many unauthenticated connections");
        }
        let (tx, rx) = oneshot::channel();
        let id = t.next_id;
        t.next_id += 1;
        t.order.push_back(Entry {
            id,
            source,
            evict: tx,
        });
        *t.per_source.entry(source).or_insert(0) += 1;
        self.gauge().store(t.order.len() as u64, Ordering::Relaxed);
        Pending {
            table: self.clone(),
            id,
            evicted: rx,
        }
    }

    fn evict(&self, t: &mut Inner, i: Option<usize>, why: Evicted) {
        if let Some(e) = i.and_then(|i| Self::take(t, i)) {
            let _ = e.evict.send(why);
            self.evictions().fetch_add(1, Ordering::Relaxed);
        }
    }

    fn take(t: &mut Inner, i: usize) -> Option<Entry> {
        let e = t.order.remove(i)?;
        if let Some(n) = t.per_source.get_mut(&e.source) {
            *n -= 1;
            if *n == 0 {
                t.per_source.remove(&e.source);
            }
        }
        Some(e)
    }

    fn remove(&self, id: u64) {
        let mut t = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(i) = t.order.iter().position(|e| e.id == id) {
            Self::take(&mut t, i);
        }
        self.gauge().store(t.order.len() as u64, Ordering::Relaxed);
    }
}

impl Pending {
    /// Resolves (with the reason) once the table has closed this connection to make room;
    /// never while it keeps its place.
    pub async fn evicted(&mut self) -> Evicted {
        match (&mut self.evicted).await {
            Ok(why) => why,
            // Only the table drops the sender, and only while removing our entry, which
            // happens through `Drop` below after we are done polling.
            Err(_) => std::future::pending().await,
        }
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        self.table.remove(self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(per: usize, total: usize) -> (Arc<PendingTable>, Arc<ServerStats>) {
        let stats = Arc::new(ServerStats::default());
        (
            Arc::new(PendingTable::new(per, total, stats.clone(), Counted::Handshakes)),
            stats,
        )
    }

    fn was_evicted(p: &mut Pending) -> bool {
        p.evicted.try_recv().is_ok()
    }

    #[test]
    fn a_source_at_its_cap_loses_its_oldest() {
        let (t, stats) = table(2, 10);
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let mut a1 = t.admit(a);
        let mut b1 = t.admit(b);
        let mut a2 = t.admit(a);
        let mut a3 = t.admit(a);
        assert!(was_evicted(&mut a1));
        assert!(!was_evicted(&mut a2) && !was_evicted(&mut a3) && !was_evicted(&mut b1));
        assert_eq!(t.len(), 3);
        assert_eq!(stats.pending.load(Ordering::Relaxed), 3);
        assert_eq!(stats.pending_evicted.load(Ordering::Relaxed), 1);
        // Authenticating (dropping) frees the place; an evicted one's drop changes nothing.
        drop(a2);
        drop(a1);
        assert_eq!(t.len(), 2);
        let mut a4 = t.admit(a);
        assert!(!was_evicted(&mut a3) && !was_evicted(&mut a4));
    }

    #[test]
    fn a_full_table_loses_its_oldest() {
        let (t, stats) = table(8, 3);
        let mut v: Vec<Pending> = (1..=3)
            .map(|i| t.admit(IpAddr::from([10, 0, 0, i])))
            .collect();
        let _n = t.admit("10.0.0.9".parse().unwrap());
        assert!(was_evicted(&mut v[0]) && !was_evicted(&mut v[1]));
        assert_eq!(t.len(), 3);
        assert_eq!(stats.pending_evicted.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn sources_are_grouped_sensibly() {
        let k = |s: &str| source_key(s.parse().unwrap());
        assert_eq!(k("::ffff:1.2.3.4"), k("1.2.3.4"));
        assert_eq!(k("2001:db8:1:2:aaaa::1"), k("2001:db8:1:2:bbbb::9"));
        assert_ne!(k("2001:db8:1:2::1"), k("2001:db8:1:3::1"));
        assert_ne!(k("1.2.3.4"), k("1.2.3.5"));
    }
}
