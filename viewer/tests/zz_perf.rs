mod common;
use common::*;
use snerf_viewer::{GpuOptions, GpuRenderer, View};
use std::time::Instant;
#[test]
fn perf() {
    setup();
    let a = object_asset();
    let (w, h) = (320, 240);
    let c = cams(&a.header, 5, w, h);
    for hw in [false, true] {
        let mut r = GpuRenderer::with_options(&a, GpuOptions { hardware_filter: hw, ..Default::default() }).unwrap();
        r.render_wait(w, h, &[View { cam: c[0], time: 0.0, x0: 0 }]).unwrap();
        let mut g = vec![];
        for i in 0..5 { g.push(r.render_wait(w, h, &[View { cam: c[i], time: 0.0, x0: 0 }]).unwrap().as_secs_f64() * 1e3); }
        let t0 = Instant::now();
        let f = snerf_asset::render(&a, &c[0], 0.0);
        let cpu = t0.elapsed().as_secs_f64() * 1e3;
        let pr = snerf_asset::render_pixel(&a, &c[0], w / 2, h / 2, 0.0);
        println!("hw {} gpu {:?} cpu {:.1} ms  centre samples {}", hw, g.iter().map(|x| *x as i64).collect::<Vec<_>>(), cpu, pr.samples);
        std::hint::black_box(f);
    }
}
