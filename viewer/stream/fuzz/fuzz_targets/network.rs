//! Any bytes a peer can send: control frames and messages (both directions), pose
//! datagrams, data-stream records fed to the client's chunk collector (a hostile server),
//! URLs and pins. Nothing may panic, hang or allocate beyond the stated limits.
#![no_main]
use libfuzzer_sys::fuzz_target;
use snerf_stream::client::Collector;
use snerf_stream::proto::{self, AssetInfo, RECORD_HEADER_LEN};

fuzz_target!(|data: &[u8]| {
    let _ = proto::decode_client_msg(data);
    let _ = proto::decode_server_msg(data);
    let _ = proto::decode_pose(data);
    let mut rest = data;
    while let Ok(Some((m, r))) = proto::split_frame(rest, 1 << 16) {
        let _ = proto::decode_client_msg(m);
        let _ = proto::decode_server_msg(m);
        rest = r;
    }
    let rt = tokio::runtime::Builder::new_current_thread()
        .build()
        .unwrap();
    let mut rd: &[u8] = data;
    let _ = rt.block_on(proto::read_frame(&mut rd, 1 << 16));
    let s = String::from_utf8_lossy(data);
    let _ = snerf_stream::parse_url(&s);
    let _ = snerf_stream::tls::parse_pin(&s);
    // Records from a hostile server into the collector / assembler.
    let info = AssetInfo {
        name: "f".into(),
        size: 1 << 20,
        chunks: 8,
        sha256: "0".repeat(64),
        preamble: proto::to_hex(&snerf_asset::preamble()),
        atlas_blocks: 4,
        frames: 1,
        geometry: None,
    };
    let mut c = Collector::new(info).unwrap();
    let mut pos = 0;
    while pos + RECORD_HEADER_LEN <= data.len() {
        let Ok((index, _, len)) =
            proto::parse_record_header(&data[pos..pos + RECORD_HEADER_LEN], 8, 1 << 16)
        else {
            break;
        };
        let end = (pos + RECORD_HEADER_LEN + len as usize).min(data.len());
        let mut chunk = data[pos + 4..pos + 16].to_vec();
        chunk.extend_from_slice(&data[pos + 16..end]);
        if c.accept(index, chunk).is_err() {
            break;
        }
        pos = end;
    }
});
