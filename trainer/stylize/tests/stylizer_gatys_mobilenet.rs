//! `gatys` on the MobileNetV2 trunk of Magenta's style network: the network read from the
//! ONNX file computes what tract computes from the same file, every convolution kind's
//! hand-written backward pass matches finite differences (on a small network and on the
//! real weights), and the stylizer moves a photo toward the style.

mod stylizer_support;

use snerf_stylize::stylizer::gatys::mobilenet::{Conv, Op};
use snerf_stylize::stylizer::gatys::{planes_from_image, style_grams, FeatureNet, GatysStylizer, MobileNet, Objective, Planes};
use snerf_stylize::stylizer::{model_path, Image, StyleEmbedder, Stylizer, ARBITRARY_PREDICT};
use stylizer_support::{assert_finite_in_range, content_image, models_or_skip, noise, shifted, style_image};

/// `(cin, cout, groups)`, kernel `k` and stride `stride`, random weights from `seed`.
fn conv((cin, cout, groups): (usize, usize, usize), k: usize, stride: usize, pad: [usize; 4], clip: bool, seed: u64) -> Conv {
    let n = cout * (cin / groups) * k * k;
    let scale = 1.5 / ((cin / groups) * k * k) as f32;
    Conv {
        cin,
        cout,
        groups,
        k,
        stride,
        pad,
        weight: noise(n, seed).iter().map(|w| w * scale.sqrt()).collect(),
        bias: noise(cout, seed + 1).iter().map(|b| 0.1 * b).collect(),
        clip: clip.then_some((0.0, 6.0)),
    }
}

/// Every op kind the reader produces, in MobileNetV2's arrangement: a dense stride-2 stem
/// with TF "SAME" padding (bottom/right only), an inverted-residual block with a shortcut,
/// a stride-2 depthwise block, and a global mean.
fn small_net() -> MobileNet {
    let ops = vec![
        Op::Conv { input: 0, conv: conv((3, 6, 1), 3, 2, [0, 0, 1, 1], true, 1) }, // act 1
        Op::Conv { input: 1, conv: conv((6, 12, 1), 1, 1, [0; 4], true, 2) },      // 2: expand
        Op::Conv { input: 2, conv: conv((12, 12, 12), 3, 1, [1; 4], true, 3) },    // 3: depthwise
        Op::Conv { input: 3, conv: conv((12, 6, 1), 1, 1, [0; 4], false, 4) },     // 4: project
        Op::Add { a: 4, b: 1 },                                                 // 5: shortcut
        Op::Conv { input: 5, conv: conv((6, 12, 1), 1, 1, [0; 4], true, 5) },      // 6
        Op::Conv { input: 6, conv: conv((12, 12, 12), 3, 2, [0, 0, 1, 1], true, 6) }, // 7: 1/4
        Op::Mean { input: 7 },                                                  // 8
        Op::Conv { input: 8, conv: conv((12, 5, 1), 1, 1, [0; 4], false, 7) },     // 9: head
    ];
    MobileNet { ops, tap_acts: vec![1, 3, 5, 7], output_act: 9 }
}

/// The same network without its activation clamps.
fn unclipped(net: &MobileNet) -> MobileNet {
    let ops = net
        .ops
        .iter()
        .map(|op| match op {
            Op::Conv { input, conv } => Op::Conv { input: *input, conv: Conv { clip: None, ..conv.clone() } },
            other => other.clone(),
        })
        .collect();
    MobileNet { ops, tap_acts: net.tap_acts.clone(), output_act: net.output_act }
}

fn check_gradient(net: &dyn FeatureNet, content: &Planes, style: &Planes, h: f32, tol: f64) {
    let grams = style_grams(net, style);
    let obj = Objective::new(net, content, &grams, 1.0, 5.0);
    let x = Planes { data: content.data.iter().zip(noise(content.data.len(), 9)).map(|(c, n)| (c + 0.1 * n).clamp(0.05, 0.95)).collect(), ..content.clone() };
    let (loss, grad) = obj.loss_and_grad(&x);
    assert!(loss > 0.0 && loss.is_finite());
    for seed in 0..4 {
        let dir = noise(x.data.len(), 100 + seed);
        let fd = (obj.loss(&shifted(&x, &dir, h)) - obj.loss(&shifted(&x, &dir, -h))) / (2.0 * h as f64);
        let an: f64 = grad.data.iter().zip(&dir).map(|(g, d)| (*g as f64) * (*d as f64)).sum();
        let rel = (fd - an).abs() / an.abs().max(fd.abs()).max(1e-8);
        println!("{}: direction {seed}: finite difference {fd:.6e}, analytic {an:.6e}, relative error {rel:.2e}", net.name());
        assert!(rel < tol, "{}: directional derivative {seed}: fd {fd} vs analytic {an}", net.name());
    }
}

#[test]
fn small_network_gradient_matches_central_differences() {
    let net = small_net();
    check_gradient(&net, &planes_from_image(&content_image(17, 15)), &planes_from_image(&style_image(20, 18)), 1e-3, 1e-2);
    // The head (mean + pointwise) too: d(sum of embedding * r)/dx, with the clamps removed
    // so the map is linear and central differences are exact up to rounding.
    let net = unclipped(&net);
    let x = planes_from_image(&content_image(17, 15));
    let r = noise(5, 77);
    let f = |x: &Planes| -> f64 { net.embedding(x).iter().zip(&r).map(|(a, b)| (*a as f64) * (*b as f64)).sum() };
    assert_eq!(net.embedding(&x).len(), 5);
    // Backward from the output through every op: the output as the only tap.
    let tr = snerf_stylize::stylizer::gatys::Trace { acts: net.run(&x, net.ops.len()), aux: Vec::new(), taps: vec![net.output_act] };
    let head = MobileNet { ops: net.ops.clone(), tap_acts: vec![net.output_act], output_act: net.output_act };
    let g = head.backward(&tr, &[Some(Planes { c: 5, h: 1, w: 1, data: r.clone() })]);
    let h = 1e-2f32;
    for seed in 0..3 {
        let dir = noise(x.data.len(), 300 + seed);
        let fd = (f(&shifted(&x, &dir, h)) - f(&shifted(&x, &dir, -h))) / (2.0 * h as f64);
        let an: f64 = g.data.iter().zip(&dir).map(|(g, d)| (*g as f64) * (*d as f64)).sum();
        let rel = (fd - an).abs() / an.abs().max(fd.abs()).max(1e-8);
        println!("head: direction {seed}: fd {fd:.6e}, analytic {an:.6e}, relative error {rel:.2e}");
        assert!(rel < 2e-3, "head derivative {seed}: fd {fd} vs analytic {an}");
    }
}

#[test]
fn real_network_matches_tract_and_its_gradient_matches_central_differences() {
    let Some(opts) = models_or_skip("real_network_matches_tract_and_its_gradient_matches_central_differences") else { return };
    let net = MobileNet::load(&model_path(ARBITRARY_PREDICT, &opts).unwrap()).unwrap();
    assert_eq!(net.taps(), 4);
    // Tap sizes on a 256x256 image: 1/2, 1/4, 1/8, 1/16.
    let img = style_image(256, 256);
    let tr = net.forward(&planes_from_image(&img));
    let sizes: Vec<(usize, usize)> = (0..4).map(|t| (tr.tap(t).c, tr.tap(t).h)).collect();
    assert_eq!(sizes, vec![(32, 128), (96, 64), (144, 32), (192, 16)]);
    // The embedding against tract running the ONNX file (which also fake-quantizes every
    // activation to int8; this reader does not, so they agree to quantization noise).
    let embedder = StyleEmbedder::new(&opts).unwrap();
    for (name, im) in [("swirls", style_image(256, 256)), ("photo", content_image(256, 256))] {
        let ours = net.embedding(&planes_from_image(&im));
        let theirs = embedder.embed(&im).unwrap();
        assert_eq!(ours.len(), theirs.len());
        let dot: f64 = ours.iter().zip(&theirs).map(|(a, b)| (*a as f64) * (*b as f64)).sum();
        let na: f64 = ours.iter().map(|a| (*a as f64).powi(2)).sum::<f64>().sqrt();
        let nb: f64 = theirs.iter().map(|a| (*a as f64).powi(2)).sum::<f64>().sqrt();
        let diff: f64 = ours.iter().zip(&theirs).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>().sqrt();
        let cos = dot / (na * nb);
        println!("{name}: cosine {cos:.4}, relative L2 difference {:.4}", diff / nb);
        assert!(cos > 0.98, "{name}: our embedding is not the ONNX file's (cosine {cos})");
        assert!(diff / nb < 0.2, "{name}: relative difference {}", diff / nb);
    }
    // A wrong graph is caught: another embedding of a different image is far away.
    let a = net.embedding(&planes_from_image(&style_image(256, 256)));
    let b = embedder.embed(&content_image(256, 256)).unwrap();
    let d: f32 = a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f32>().sqrt();
    let n: f32 = b.iter().map(|x| x * x).sum::<f32>().sqrt();
    assert!(d / n > 0.2, "the comparison cannot tell two images apart ({})", d / n);

    // The real graph's gradient (its strides, paddings, groups and shortcuts, with the real
    // weights). Its thousands of ReLU6 kinks bend any secant wide enough to rise above f32
    // rounding, so the clamps come out here; the small network above checks them.
    check_gradient(&unclipped(&net), &planes_from_image(&content_image(32, 32)), &planes_from_image(&style_image(48, 48)), 1e-3, 1e-2);
}

#[test]
fn gatys_without_weight_files_uses_the_installed_network_and_moves_toward_the_style() {
    let Some(mut opts) = models_or_skip("gatys_without_weight_files_uses_the_installed_network_and_moves_toward_the_style") else { return };
    opts.gatys_steps = 60;
    let style = style_image(128, 128);
    let s = GatysStylizer::from_options(&style, &opts).unwrap();
    assert_eq!(s.features(), "mobilenet_v2");
    let content = content_image(96, 80);
    let (out, losses) = s.stylize_with_losses(&content).unwrap();
    assert_finite_in_range(&out);
    assert_eq!((out.width, out.height), (96, 80));
    println!("loss {:.4} -> {:.4}", losses[0], losses.last().unwrap());
    assert!(*losses.last().unwrap() < 0.5 * losses[0], "loss {:?}", (losses[0], losses.last()));
    // The view changed, but it is still the view (started from it, content-anchored).
    let mad = |a: &Image, b: &Image| a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.data.len() as f32;
    let moved = mad(&out, &content);
    println!("mean absolute change {moved:.4}");
    assert!(moved > 0.02 && moved < 0.3, "change {moved}");
    assert_eq!(s.name(), "gatys");
    // Without a style image it is an error that says so.
    let e = snerf_stylize::stylizer::from_spec("gatys", None, &opts).err().unwrap().to_string();
    assert!(e.contains("style image"), "{e}");
}
