//! `LiveAsset`: the progressive client a viewer renders from while blocks stream in. A
//! background thread runs the connection; the viewer polls `generation()`, renders through
//! `with_asset` (header, grids and MLP first, blocks filling in) and sends its pose with
//! `set_pose`, which the server uses to send what the viewer is looking at first.

use anyhow::{anyhow, Context, Result};
use bytes::Bytes;
use quinn::{Connection, VarInt};
use snerf_asset::Asset;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

use crate::client::{open_session, receive, ClientOptions, Collector, Record};
use crate::proto::{code, encode_pose, AssetInfo, ClientMsg, Pose, PROTOCOL_VERSION};
use crate::url::{parse_url, resolve};

struct State {
    collector: Collector,
    new_blocks: Vec<u32>,
    error: Option<String>,
    ttr: Option<Duration>,
    complete_at: Option<Duration>,
}

struct Shared {
    state: Mutex<State>,
    generation: AtomicU64,
    bytes: Arc<AtomicU64>,
    pose: Mutex<Option<Pose>>,
    seq: AtomicU32,
    conn: Connection,
    info: AssetInfo,
    done: AtomicBool,
    started: Instant,
}

impl Shared {
    fn send_pose(&self) {
        if let Some(p) = *self.pose.lock().unwrap_or_else(std::sync::PoisonError::into_inner) {
            let seq = self.seq.fetch_add(1, Ordering::Relaxed) + 1;
            let _ = self
                .conn
                .send_datagram(Bytes::copy_from_slice(&encode_pose(seq, &p)));
        }
    }
}

struct Guard {
    stop: watch::Sender<bool>,
}

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.stop.send(true);
    }
}

/// A streaming asset; clones share one connection. Dropping the last clone closes it.
#[derive(Clone)]
pub struct LiveAsset {
    shared: Arc<Shared>,
    _guard: Arc<Guard>,
}

impl LiveAsset {
    /// Connect and authenticate; returns once the server accepted (errors such as a wrong
    /// token, pin or asset name come back here). Data then arrives in the background.
    pub fn connect(url: &str, pin: &str, token: &str) -> Result<LiveAsset> {
        LiveAsset::connect_with(url, pin, token, ClientOptions::default())
    }

    /// `connect` with options (e.g. `opts.pose`: the first view, so its blocks come first).
    pub fn connect_with(
        url: &str,
        pin: &str,
        token: &str,
        opts: ClientOptions,
    ) -> Result<LiveAsset> {
        let (hp, asset) = parse_url(url)?;
        let addr = resolve(&hp)?;
        let (pin, token, url) = (pin.to_string(), token.to_string(), url.to_string());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(Arc<Shared>, Arc<Guard>)>>();
        std::thread::Builder::new()
            .name("snerf-live".into())
            .spawn(move || {
                let rt = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
                    Ok(rt) => rt,
                    Err(e) => {
                        let _ = ready_tx.send(Err(anyhow!("cannot start the client runtime: {}", e)));
                        return;
                    }
                };
                rt.block_on(async move {
                    let hello = ClientMsg::Hello {
                        version: PROTOCOL_VERSION,
                        token,
                        asset: Some(asset),
                        have: vec![],
                        resume_id: None,
                        pose: opts.pose,
                        colour_of: None,
                    };
                    let session = match open_session(addr, &pin, hello, &opts).await {
                        Ok(s) => s,
                        Err(e) => {
                            let _ = ready_tx.send(Err(e.context(format!("connecting to {}", url))));
                            return;
                        }
                    };
                    let Some(info) = session.asset.clone() else {
                        let _ = ready_tx.send(Err(anyhow!("server sent no asset information")));
                        return;
                    };
                    let collector = match Collector::new(info.clone()) {
                        Ok(c) => c,
                        Err(e) => {
                            let _ = ready_tx.send(Err(e));
                            return;
                        }
                    };
                    let shared = Arc::new(Shared {
                        state: Mutex::new(State { collector, new_blocks: vec![], error: None, ttr: None, complete_at: None }),
                        generation: AtomicU64::new(0),
                        bytes: Arc::new(AtomicU64::new(0)),
                        pose: Mutex::new(opts.pose),
                        seq: AtomicU32::new(0),
                        conn: session.conn.clone(),
                        info: info.clone(),
                        done: AtomicBool::new(false),
                        started: session.started,
                    });
                    let (stop, mut stop_rx) = watch::channel(false);
                    let guard = Arc::new(Guard { stop });
                    if ready_tx.send(Ok((shared.clone(), guard))).is_err() {
                        session.close();
                        return;
                    }
                    let (tx, mut rx) = mpsc::channel::<Record>(256);
                    let recv = tokio::spawn(receive(session.conn.clone(), info, tx, shared.bytes.clone(), opts.abort_after_bytes));
                    let mut tick = tokio::time::interval(Duration::from_millis(250));
                    loop {
                        tokio::select! {
                            r = rx.recv() => match r {
                                None => break,
                                Some(rec) => {
                                    let mut st = shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                                    match st.collector.accept(rec.index, rec.chunk) {
                                        Ok((a, _)) => {
                                            if a.new {
                                                st.new_blocks.extend(a.blocks);
                                                if a.became_renderable {
                                                    st.ttr = Some(shared.started.elapsed());
                                                }
                                                if st.collector.is_complete() {
                                                    st.complete_at = Some(shared.started.elapsed());
                                                }
                                                drop(st);
                                                shared.generation.fetch_add(1, Ordering::Release);
                                            }
                                        }
                                        Err(e) => {
                                            st.error = Some(format!("server sent bad data: {:#}", e));
                                            drop(st);
                                            session.conn.close(VarInt::from_u32(code::CLIENT_REJECT), b"bad chunk");
                                            shared.generation.fetch_add(1, Ordering::Release);
                                            break;
                                        }
                                    }
                                    if shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).collector.is_complete() {
                                        break;
                                    }
                                }
                            },
                            _ = tick.tick() => shared.send_pose(), // datagrams may be lost: repeat
                            _ = stop_rx.wait_for(|s| *s) => break,
                        }
                    }
                    let complete = shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).collector.is_complete();
                    if complete {
                        session.close();
                    } else {
                        let mut st = shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                        if st.error.is_none() && !*stop_rx.borrow() {
                            let why = session.close_error().map(|e| format!("{:#}", e)).unwrap_or_else(|| "connection ended".into());
                            st.error = Some(format!("stream interrupted: {}", why));
                        }
                        drop(st);
                        session.conn.close(VarInt::from_u32(code::DONE), b"client leaving");
                    }
                    recv.abort();
                    shared.done.store(true, Ordering::Release);
                    shared.generation.fetch_add(1, Ordering::Release);
                    let _ = tokio::time::timeout(Duration::from_secs(2), session.endpoint.wait_idle()).await;
                });
            })
            .context("cannot spawn the client thread")?;
        let (shared, guard) = ready_rx
            .recv()
            .map_err(|_| anyhow!("client thread ended during connect"))??;
        Ok(LiveAsset {
            shared,
            _guard: guard,
        })
    }

    pub fn info(&self) -> &AssetInfo {
        &self.shared.info
    }

    /// Bumps whenever chunks arrived (or the stream ended).
    pub fn generation(&self) -> u64 {
        self.shared.generation.load(Ordering::Acquire)
    }

    /// Run `f` on the partial asset once header, MLP and every grid have arrived (missing
    /// blocks render empty); None before that.
    pub fn with_asset<R>(&self, f: impl FnOnce(&Asset) -> R) -> Option<R> {
        let st = self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if !st.collector.renderable {
            return None;
        }
        st.collector.asm.as_ref().map(|a| f(a.asset()))
    }

    /// Atlas block indices that arrived since the last call.
    pub fn take_new_blocks(&self) -> Vec<u32> {
        std::mem::take(&mut self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).new_blocks)
    }

    /// Tell the server where the viewer is (world space); sent as a datagram at once and
    /// repeated while streaming.
    pub fn set_pose(&self, eye: [f32; 3], forward: [f32; 3]) {
        let mut p = self
            .shared
            .pose
            .lock()
            .unwrap()
            .unwrap_or(Pose::new(eye, forward));
        p.eye = eye;
        p.forward = forward;
        self.set_pose_full(p);
    }

    /// Pose with playback time (dynamic assets) and field of view.
    pub fn set_pose_full(&self, p: Pose) {
        if p.validate().is_err() {
            return;
        }
        *self.shared.pose.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(p);
        self.shared.send_pose();
    }

    pub fn is_complete(&self) -> bool {
        self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).collector.is_complete()
    }

    /// Whether the background connection has ended (complete, failed or closed).
    pub fn is_finished(&self) -> bool {
        self.shared.done.load(Ordering::Acquire)
    }

    pub fn error(&self) -> Option<String> {
        self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).error.clone()
    }

    /// Connect start -> header, grids and MLP present.
    pub fn time_to_renderable(&self) -> Option<Duration> {
        self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).ttr
    }

    /// Connect start -> every chunk present.
    pub fn time_to_complete(&self) -> Option<Duration> {
        self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).complete_at
    }

    /// Time since connect started.
    pub fn elapsed(&self) -> Duration {
        self.shared.started.elapsed()
    }

    /// Record bytes received so far.
    pub fn bytes_received(&self) -> u64 {
        self.shared.bytes.load(Ordering::Relaxed)
    }

    /// Which atlas blocks are present now.
    pub fn present_blocks(&self) -> Vec<bool> {
        let st = self.shared.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        st.collector
            .asm
            .as_ref()
            .map(|a| a.asset().present.clone())
            .unwrap_or_default()
    }

    /// Block until complete, failed, or `timeout`.
    pub fn wait(&self, timeout: Duration) -> Result<()> {
        let t0 = Instant::now();
        loop {
            if self.is_complete() {
                return Ok(());
            }
            if let Some(e) = self.error() {
                return Err(anyhow!(e));
            }
            if t0.elapsed() > timeout {
                return Err(anyhow!("not complete after {:?}", timeout));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}
