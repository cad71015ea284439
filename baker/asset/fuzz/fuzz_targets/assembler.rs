//! Streaming: a valid-looking preamble + HEAD prefix, then arbitrary chunks pushed one by
//! one (with and without CRC checks); the partial asset must stay renderable.
#![no_main]
use libfuzzer_sys::fuzz_target;
use snerf_asset::chunk::parse_chunk_at;
use snerf_asset::render::render_ray;
use snerf_asset::Assembler;

fuzz_target!(|data: &[u8]| {
    let Ok(head) = parse_chunk_at(data, 16, 0) else { return };
    let Ok(mut asm) = Assembler::new(&data[..head.range.end]) else { return };
    let mut pos = head.range.end;
    let mut i = 1;
    while pos < data.len() {
        match parse_chunk_at(data, pos, i) {
            Ok(c) => {
                if i % 2 == 0 {
                    let _ = asm.push_chunk(&data[c.range.clone()]);
                } else {
                    let _ = asm.push(c.tag, &data[c.payload.clone()]);
                }
                pos = c.range.end;
                i += 1;
            }
            Err(_) => break,
        }
    }
    let _ = asm.is_complete();
    let _ = asm.missing_blocks();
    let _ = render_ray(asm.asset(), [0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 0.0);
});
