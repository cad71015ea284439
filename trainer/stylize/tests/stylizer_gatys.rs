//! `gatys`: hand-written VGG backward checked against finite differences, the optimisation
//! lowering the loss, and every kind of bad weights file.

mod stylizer_support;

use std::path::Path;

use snerf_stylize::stylizer::gatys::{optimize, planes_from_image, style_grams, GatysStylizer, Objective, Planes, Vgg, VggWeights, CONV_INDICES};
use snerf_stylize::stylizer::{from_spec, save_png, Stylizer, StylizerOptions};
use stylizer_support::{assert_finite_in_range, content_image, noise, shifted, style_image};

#[test]
fn gradient_matches_central_differences() {
    let vgg = Vgg::new(VggWeights::random([4, 6, 8, 8], 3));
    let content = planes_from_image(&content_image(16, 16));
    let style = planes_from_image(&style_image(24, 20));
    let grams = style_grams(&vgg, &style);
    let obj = Objective::new(&vgg, &content, &grams, 1.0, 5.0);
    // Evaluate away from the content so the content term has a gradient too.
    let x = Planes { data: content.data.iter().zip(noise(content.data.len(), 9)).map(|(c, n)| (c + 0.1 * n).clamp(0.05, 0.95)).collect(), ..content.clone() };
    let (loss, grad) = obj.loss_and_grad(&x);
    assert!(loss > 0.0 && loss.is_finite());
    // Small enough that few ReLU/max-pool switches fall inside [x - h, x + h] (at 1e-3 they
    // shift this tiny network's derivatives by a few percent), large enough for f32.
    let h = 1e-4f32;

    // Directional derivatives along random directions.
    for seed in 0..4 {
        let dir = noise(x.data.len(), 100 + seed);
        let fd = (obj.loss(&shifted(&x, &dir, h)) - obj.loss(&shifted(&x, &dir, -h))) / (2.0 * h as f64);
        let an: f64 = grad.data.iter().zip(&dir).map(|(g, d)| (*g as f64) * (*d as f64)).sum();
        let rel = (fd - an).abs() / an.abs().max(fd.abs()).max(1e-8);
        println!("direction {seed}: finite difference {fd:.6e}, analytic {an:.6e}, relative error {rel:.2e}");
        assert!(rel < 1e-2, "directional derivative {seed}: fd {fd} vs analytic {an}");
    }

    // Single pixels with the largest gradients.
    let mut idx: Vec<usize> = (0..grad.data.len()).collect();
    idx.sort_by(|a, b| grad.data[*b].abs().total_cmp(&grad.data[*a].abs()));
    let mut worst = 0.0f64;
    for &i in idx.iter().take(12) {
        let mut e = vec![0.0f32; x.data.len()];
        e[i] = 1.0;
        let fd = (obj.loss(&shifted(&x, &e, h)) - obj.loss(&shifted(&x, &e, -h))) / (2.0 * h as f64);
        let an = grad.data[i] as f64;
        worst = worst.max((fd - an).abs() / an.abs().max(fd.abs()));
    }
    println!("largest-gradient pixels: worst relative error {worst:.2e}");
    assert!(worst < 2e-2, "per-pixel gradient relative error {worst}");
}

#[test]
fn optimisation_lowers_the_loss() {
    let weights = VggWeights::random([8, 12, 16, 16], 5);
    let vgg = Vgg::new(weights);
    let content = planes_from_image(&content_image(48, 40));
    let grams = style_grams(&vgg, &planes_from_image(&style_image(48, 48)));
    let obj = Objective::new(&vgg, &content, &grams, 1.0, 5.0);
    let (out, losses) = optimize(&obj, &content, 40, 0.02);
    let final_loss = obj.loss(&out);
    println!("loss: first {:.4}, step 10 {:.4}, step 20 {:.4}, final {:.4}", losses[0], losses[10], losses[20], final_loss);
    assert!(final_loss < 0.6 * losses[0], "loss did not fall enough: {} -> {final_loss}", losses[0]);
    assert!(losses[20] < losses[0] && losses[39] < losses[20]);
    assert!(out.data.iter().all(|v| (0.0..=1.0).contains(v)));
}

fn write_weights(path: &Path, w: &VggWeights) {
    std::fs::write(path, w.to_safetensors().unwrap()).unwrap();
}

#[test]
fn stylizer_from_spec_with_a_weights_file() {
    let dir = tempfile::tempdir().unwrap();
    let weights = dir.path().join("vgg.safetensors");
    write_weights(&weights, &VggWeights::random([8, 8, 12, 12], 11));
    let style = dir.path().join("style.png");
    save_png(&style, &style_image(64, 64)).unwrap();
    let opts = StylizerOptions { gatys_weights: Some(weights), gatys_steps: 15, content_size: 64, ..Default::default() };
    let s = from_spec("gatys", Some(&style), &opts).unwrap();
    assert_eq!(s.name(), "gatys");
    // 100x70 is optimised at 64x45 and resized back.
    let content = content_image(100, 70);
    let out = s.stylize(&content).unwrap();
    assert_eq!((out.width, out.height), (100, 70));
    assert_finite_in_range(&out);
    assert!(out.mean_abs_diff(&content) > 0.01, "gatys did not change the view");
    let zero = GatysStylizer::from_file(opts.gatys_weights.as_ref().unwrap(), &style_image(64, 64), &StylizerOptions { strength: 0.0, ..opts.clone() }).unwrap();
    assert_eq!(zero.stylize(&content).unwrap(), content);
}

fn expect_error(path: &Path, needles: &[&str]) {
    let err = format!("{:#}", VggWeights::load(path).unwrap_err());
    assert!(err.contains(&path.display().to_string()), "error does not name the file: {err}");
    for n in needles {
        assert!(err.contains(n), "error lacks {n:?}: {err}");
    }
}

/// Rewrites the tensors of `w` with `edit` applied to the (name, shape, bytes) list.
fn write_edited(path: &Path, w: &VggWeights, edit: impl FnOnce(&mut Vec<(String, Vec<usize>, Vec<u8>, safetensors::Dtype)>)) {
    let mut tensors = Vec::new();
    for (conv, k) in w.convs.iter().zip(CONV_INDICES) {
        let bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        tensors.push((format!("features.{k}.weight"), vec![conv.cout, conv.cin, 3, 3], bytes(&conv.weight), safetensors::Dtype::F32));
        tensors.push((format!("features.{k}.bias"), vec![conv.cout], bytes(&conv.bias), safetensors::Dtype::F32));
    }
    edit(&mut tensors);
    let views: Vec<(String, safetensors::tensor::TensorView)> =
        tensors.iter().map(|(n, s, b, d)| (n.clone(), safetensors::tensor::TensorView::new(*d, s.clone(), b).unwrap())).collect();
    std::fs::write(path, safetensors::serialize(views, &None).unwrap()).unwrap();
}

#[test]
fn bad_weight_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let w = VggWeights::random([4, 4, 4, 4], 1);

    expect_error(&dir.path().join("missing.safetensors"), &["cannot read"]);

    let good = dir.path().join("good.safetensors");
    write_weights(&good, &w);
    VggWeights::load(&good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let truncated = dir.path().join("truncated.safetensors");
    std::fs::write(&truncated, &bytes[..bytes.len() - 100]).unwrap();
    expect_error(&truncated, &["not a valid safetensors file"]);

    let text = dir.path().join("text.safetensors");
    std::fs::write(&text, "hello, I am not a tensor file").unwrap();
    expect_error(&text, &["not a valid safetensors file"]);

    let missing = dir.path().join("missing_tensor.safetensors");
    write_edited(&missing, &w, |t| t.retain(|(n, ..)| n != "features.10.weight"));
    expect_error(&missing, &["missing tensor features.10.weight"]);

    let wrong_in = dir.path().join("wrong_cin.safetensors");
    let mut w2 = w.clone();
    w2.convs[3] = snerf_stylize::stylizer::gatys::Conv3x3 { cout: 4, cin: 5, weight: vec![0.1; 4 * 5 * 9], bias: vec![0.0; 4] };
    write_weights(&wrong_in, &w2);
    expect_error(&wrong_in, &["features.7.weight", "conv2_2", "5 input channels"]);

    let wrong_kernel = dir.path().join("wrong_kernel.safetensors");
    write_edited(&wrong_kernel, &w, |t| {
        let e = t.iter_mut().find(|(n, ..)| n == "features.0.weight").unwrap();
        e.1 = vec![4, 3, 9];
    });
    expect_error(&wrong_kernel, &["features.0.weight", "[4, 3, 9]"]);

    let wrong_bias = dir.path().join("wrong_bias.safetensors");
    write_edited(&wrong_bias, &w, |t| {
        let e = t.iter_mut().find(|(n, ..)| n == "features.2.bias").unwrap();
        e.1 = vec![2, 2];
    });
    expect_error(&wrong_bias, &["features.2.bias", "expected [4]"]);

    let int_dtype = dir.path().join("int.safetensors");
    write_edited(&int_dtype, &w, |t| {
        let e = t.iter_mut().find(|(n, ..)| n == "features.5.bias").unwrap();
        e.3 = safetensors::Dtype::I32;
    });
    expect_error(&int_dtype, &["features.5.bias", "float32"]);

    // torchvision's `features.state_dict()` keys lack the prefix: accepted.
    let unprefixed = dir.path().join("unprefixed.safetensors");
    write_edited(&unprefixed, &w, |t| t.iter_mut().for_each(|e| e.0 = e.0.trim_start_matches("features.").to_string()));
    assert_eq!(VggWeights::load(&unprefixed).unwrap().convs[7].weight, w.convs[7].weight);

    // Through the spec, a missing weights option explains how to get weights.
    let style = dir.path().join("s.png");
    save_png(&style, &style_image(32, 32)).unwrap();
    let e = from_spec("gatys", Some(&style), &StylizerOptions { gatys_weights: Some(truncated.clone()), ..Default::default() }).err().unwrap();
    assert!(format!("{e:#}").contains("truncated.safetensors"));
}
