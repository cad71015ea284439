//! Hearing of new styles (PROTOCOL.md, "New styles"): a session that asks for the listing
//! with `watch` is sent a `styles` message whenever a served multi-style asset gains a style
//! (`snerf serve --styles-dir` trains and adds them while it serves). The style is then
//! streamed like any other (`NAME.STYLE`), or switched to by colour (`restyle`). A client
//! may also ask for one of the paintings the listing offers to be trained (`add_style`).

use anyhow::{anyhow, bail, Context, Result};
use std::collections::VecDeque;
use std::time::Duration;

use crate::client::{open_session, ClientOptions, Session};
use crate::proto::{ClientMsg, ListEntry, ServerMsg, PROTOCOL_VERSION};
use crate::url::{parse_url, resolve};

/// A multi-style asset's styles, as a `styles` message gives them.
#[derive(Clone, Debug, PartialEq)]
pub struct NewStyles {
    pub asset: String,
    pub styles: Vec<snerf_asset::StyleInfo>,
}

/// Open a watching session on the server of `url` (quic://HOST:PORT/…): the listing now, then
/// `next_styles` for each change.
pub async fn watch(url: &str, pin: &str, token: &str) -> Result<(Session, Vec<ListEntry>)> {
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
    s.send
        .write_all(&crate::proto::encode_frame(&ClientMsg::List { thumbs: false, watch: true }))
        .await
        .map_err(|e| anyhow!("control stream: {}", e))?;
    match s.read_msg().await? {
        ServerMsg::Listing { assets } => Ok((s, assets)),
        other => bail!("unexpected server message {:?}", other),
    }
}

/// The next `styles` message of a watching session.
pub async fn next_styles(s: &mut Session) -> Result<NewStyles> {
    match s.read_msg().await? {
        ServerMsg::Styles { asset, styles } => Ok(NewStyles { asset, styles }),
        other => bail!("unexpected server message {:?}", other),
    }
}

/// Ask the server to train `painting` (a key its listing offers, `ListEntry::paintings`) as
/// a new style of `asset`; returns the style's name once the server has queued it. `Styles`
/// messages that arrive meanwhile go to `early`.
pub async fn add_style(s: &mut Session, asset: &str, painting: &str, early: &mut VecDeque<NewStyles>) -> Result<String> {
    let m = ClientMsg::AddStyle { asset: asset.to_string(), painting: painting.to_string() };
    s.send.write_all(&crate::proto::encode_frame(&m)).await.map_err(|e| anyhow!("control stream: {}", e))?;
    loop {
        match s.read_msg().await? {
            ServerMsg::Training { style, .. } => return Ok(style),
            ServerMsg::Styles { asset, styles } => early.push_back(NewStyles { asset, styles }),
            other => bail!("unexpected server message {:?}", other),
        }
    }
}

/// `watch` for synchronous callers: the session on a runtime of its own, whose worker keeps
/// the connection alive between calls.
pub struct StyleWatch {
    rt: tokio::runtime::Runtime,
    session: Session,
    /// The listing when the watch began.
    pub listing: Vec<ListEntry>,
    early: VecDeque<NewStyles>,
}

impl StyleWatch {
    pub fn open(url: &str, pin: &str, token: &str) -> Result<StyleWatch> {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .context("cannot start the tokio runtime")?;
        let (session, listing) = rt.block_on(watch(url, pin, token))?;
        Ok(StyleWatch { rt, session, listing, early: VecDeque::new() })
    }

    /// `add_style` on this watch's session.
    pub fn add_style(&mut self, asset: &str, painting: &str) -> Result<String> {
        let (s, early) = (&mut self.session, &mut self.early);
        self.rt.block_on(add_style(s, asset, painting, early))
    }

    /// The next change, or None when none came within `timeout`.
    pub fn next(&mut self, timeout: Duration) -> Result<Option<NewStyles>> {
        if let Some(n) = self.early.pop_front() {
            return Ok(Some(n));
        }
        let s = &mut self.session;
        self.rt.block_on(async { tokio::time::timeout(timeout, next_styles(s)).await.ok().transpose() })
    }
}

impl Drop for StyleWatch {
    fn drop(&mut self) {
        self.session.close();
    }
}
