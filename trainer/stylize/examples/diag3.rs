use snerf_stylize::style_metric::{self, StyleSamples};
use snerf_stylize::stylizer::Image;
use snerf_trainer::eval::{eval_background, render_camera};
use snerf_trainer::run_dir::RunDir;
use std::path::Path;
fn read(p: &Path) -> Image {
    let img = image::open(p).unwrap().to_rgb32f();
    Image { width: img.width() as usize, height: img.height() as usize, data: img.into_raw() }
}
fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let (realistic_run, srun, data_dir, style) = (&a[1], &a[2], &a[3], &a[4]);
    let data = snerf_data::load(Path::new(data_dir), &Default::default())?;
    let (realistic, pool) = RunDir::new(Path::new(realistic_run)).load_model()?;
    let (st, spool) = RunDir::new(Path::new(srun)).load_model()?;
    let stylizer = snerf_stylize::stylizer::from_spec("arbitrary", Some(Path::new(style)), &Default::default())?;
    let bg = eval_background(true);
    let idx: Vec<usize> = (0..data.train.len()).step_by(data.train.len() / 16).collect();
    let (mut masks, mut raw, mut tg, mut fr, mut r5) = (vec![], vec![], vec![], vec![], vec![]);
    for &i in &idx {
        let v = &data.train[i];
        let r = render_camera(&realistic, &pool, &v.c2w, &v.intrinsics, None, bg);
        let m: Vec<bool> = r.opacity.iter().map(|&o| o > 0.5).collect();
        let content = Image { width: r.width, height: r.height, data: r.rgb };
        raw.push(snerf_stylize::snerf_loop::stylize_region(stylizer.as_ref(), &content, Some(&m), 0)?);
        let s = render_camera(&st, &spool, &v.c2w, &v.intrinsics, None, bg);
        fr.push(Image { width: s.width, height: s.height, data: s.rgb });
        tg.push(read(&Path::new(srun).join(format!("consensus/round_4/view_{i:03}.png"))));
        r5.push(read(&Path::new(srun).join(format!("targets/round_5/view_{i:03}.png"))));
        masks.push(m);
    }
    let sty = read(Path::new(style));
    let reference = style_metric::reference(&sty, raw[0].width, raw[0].height);
    for (name, set) in [("raw stylization", &raw), ("consensus r4", &tg), ("targets r5", &r5), ("field render", &fr)] {
        let pairs: Vec<(&Image, Option<&[bool]>)> = set.iter().zip(&masks).map(|(f, m)| (f, Some(m.as_slice()))).collect();
        let d = style_metric::distance(&StyleSamples::of(&pairs), &reference);
        println!("{name:16} total {:.3} colour {:.3} texture {:.3} missed {:.3}", d.total, d.color, d.texture, d.missed);
    }
    // held-out test views: raw stylization against the field
    let (mut tm, mut traw, mut tfr) = (vec![], vec![], vec![]);
    for v in data.test.iter() {
        let r = render_camera(&realistic, &pool, &v.c2w, &v.intrinsics, None, bg);
        let m: Vec<bool> = r.opacity.iter().map(|&o| o > 0.5).collect();
        let content = Image { width: r.width, height: r.height, data: r.rgb };
        traw.push(snerf_stylize::snerf_loop::stylize_region(stylizer.as_ref(), &content, Some(&m), 0)?);
        let s = render_camera(&st, &spool, &v.c2w, &v.intrinsics, None, bg);
        tfr.push(Image { width: s.width, height: s.height, data: s.rgb });
        tm.push(m);
    }
    for (name, set) in [("TEST raw", &traw), ("TEST field", &tfr)] {
        let pairs: Vec<(&Image, Option<&[bool]>)> = set.iter().zip(&tm).map(|(f, m)| (f, Some(m.as_slice()))).collect();
        let d = style_metric::distance(&StyleSamples::of(&pairs), &reference);
        println!("{name:16} total {:.3} colour {:.3} texture {:.3} missed {:.3}", d.total, d.color, d.texture, d.missed);
    }
    Ok(())
}
