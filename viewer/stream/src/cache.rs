//! The server's loaded assets, bounded by total bytes (`Limits::cache_bytes`) with
//! least-recently-used eviction. Without a bound, a client cycling through the assets of a
//! large directory would make the server hold every file in memory at once.
//!
//! An entry counts its file size against the bound while the cache holds it. Evicting only
//! drops the cache's reference: clients still streaming the asset keep it alive, and a weak
//! reference lets a new client share that copy instead of loading a second one (which would
//! double the memory the bound was meant to cap). An asset larger than the whole bound is
//! served but never held.

use std::collections::HashMap;
use std::sync::{Arc, Weak};
use std::time::SystemTime;

struct Entry<T> {
    /// File mtime and size the asset was loaded at: a change on disk means a stale entry.
    mtime: SystemTime,
    len: u64,
    asset: Weak<T>,
    /// Set while the entry counts against the limit.
    held: Option<Arc<T>>,
    /// Last use, from `AssetCache::tick`.
    used: u64,
}

pub(crate) struct AssetCache<T> {
    limit: u64,
    bytes: u64,
    tick: u64,
    evictions: u64,
    entries: HashMap<String, Entry<T>>,
}

impl<T> AssetCache<T> {
    pub fn new(limit: u64) -> AssetCache<T> {
        AssetCache {
            limit,
            bytes: 0,
            tick: 0,
            evictions: 0,
            entries: HashMap::new(),
        }
    }

    /// Bytes held now (never above the limit).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Entries dropped to make room so far.
    pub fn evictions(&self) -> u64 {
        self.evictions
    }

    /// The asset loaded for `name` if it is still the file on disk (same mtime and size),
    /// held or still alive in some client; a hit becomes the most recently used entry.
    pub fn get(&mut self, name: &str, mtime: SystemTime, len: u64) -> Option<Arc<T>> {
        let e = self.entries.get(name)?;
        let alive = (e.mtime == mtime && e.len == len)
            .then(|| e.asset.upgrade())
            .flatten();
        let Some(a) = alive else {
            self.remove(name);
            return None;
        };
        self.hold(name, &a);
        Some(a)
    }

    /// Record a freshly loaded asset (replacing any older version of `name`).
    pub fn insert(&mut self, name: &str, mtime: SystemTime, len: u64, asset: &Arc<T>) {
        self.remove(name);
        // Forget entries nobody holds any more, so the map stays as small as what is alive.
        self.entries
            .retain(|_, e| e.held.is_some() || e.asset.strong_count() > 0);
        self.entries.insert(
            name.to_string(),
            Entry {
                mtime,
                len,
                asset: Arc::downgrade(asset),
                held: None,
                used: 0,
            },
        );
        self.hold(name, asset);
    }

    /// Make `name` the most recently used entry and count it against the limit, evicting the
    /// least recently used others until it fits. Too large to ever fit: not held.
    fn hold(&mut self, name: &str, asset: &Arc<T>) {
        self.tick += 1;
        let tick = self.tick;
        let Some(e) = self.entries.get_mut(name) else {
            return;
        };
        e.used = tick;
        if e.held.is_some() || e.len > self.limit {
            return;
        }
        let len = e.len;
        while self.bytes + len > self.limit {
            let Some(victim) = self.least_recently_used(name) else {
                break;
            };
            self.release(&victim);
            self.evictions += 1;
        }
        if let Some(e) = self.entries.get_mut(name) {
            e.held = Some(asset.clone());
            self.bytes += len;
        }
    }

    fn least_recently_used(&self, except: &str) -> Option<String> {
        self.entries
            .iter()
            .filter(|(n, e)| e.held.is_some() && n.as_str() != except)
            .min_by_key(|(_, e)| e.used)
            .map(|(n, _)| n.clone())
    }

    /// Stop counting `name` against the limit (its weak reference stays).
    fn release(&mut self, name: &str) {
        if let Some(e) = self.entries.get_mut(name) {
            if e.held.take().is_some() {
                self.bytes -= e.len;
            }
        }
    }

    fn remove(&mut self, name: &str) {
        self.release(name);
        self.entries.remove(name);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn t(s: u64) -> SystemTime {
        SystemTime::UNIX_EPOCH + Duration::from_secs(s)
    }

    #[test]
    fn evicts_least_recently_used_and_stays_under_the_limit() {
        let mut c: AssetCache<&'static str> = AssetCache::new(100);
        let (a, b, d) = (Arc::new("a"), Arc::new("b"), Arc::new("d"));
        c.insert("a", t(1), 40, &a);
        c.insert("b", t(1), 40, &b);
        assert_eq!(c.bytes(), 80);
        // Touch a, so b is the least recently used when d needs room.
        assert!(c.get("a", t(1), 40).is_some());
        c.insert("d", t(1), 40, &d);
        assert_eq!(c.bytes(), 80);
        assert_eq!(c.evictions(), 1);
        assert!(c.entries["b"].held.is_none() && c.entries["a"].held.is_some());
        // b is still alive (we hold `b`): found again, taken back in, evicting a (now LRU).
        assert!(Arc::ptr_eq(&c.get("b", t(1), 40).unwrap(), &b));
        assert_eq!(c.bytes(), 80);
        assert!(c.entries["a"].held.is_none());
        // Once nobody holds an evicted asset it is gone.
        drop(a);
        assert!(c.get("a", t(1), 40).is_none());
        // A changed file is a miss.
        assert!(c.get("b", t(2), 40).is_none());
        assert_eq!(c.bytes(), 40);
    }

    #[test]
    fn an_asset_larger_than_the_limit_is_never_held() {
        let mut c: AssetCache<u8> = AssetCache::new(100);
        let small = Arc::new(1);
        c.insert("small", t(1), 60, &small);
        let big = Arc::new(2);
        c.insert("big", t(1), 101, &big);
        assert_eq!(c.bytes(), 60, "the big one must not evict anything");
        // Shared while alive, without counting.
        assert!(c.get("big", t(1), 101).is_some());
        assert_eq!(c.bytes(), 60);
        drop(big);
        assert!(c.get("big", t(1), 101).is_none());
    }
}
