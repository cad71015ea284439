//! `color`: deterministic covariance colour transfer.

mod stylizer_support;

use snerf_stylize::stylizer::{color_transfer, from_spec, mean_and_covariance, save_png, Image, StylizerOptions};
use stylizer_support::{assert_finite_in_range, content_image, style_image};

#[test]
fn matches_the_style_mean_and_covariance() {
    let content = content_image(160, 120);
    // A style whose colours stay well inside [0,1] after transfer, so clamping is rare.
    let style: Image = {
        let s = style_image(100, 100);
        Image { data: s.data.iter().map(|v| 0.3 + 0.4 * v).collect(), ..s }
    };
    let out = color_transfer(&content, &style, 1.0);
    assert_finite_in_range(&out);
    let (mo, co) = mean_and_covariance(&out);
    let (ms, cs) = mean_and_covariance(&style);
    for c in 0..3 {
        assert!((mo[c] - ms[c]).abs() < 0.01, "channel {c} mean {} vs style {}", mo[c], ms[c]);
        for k in 0..3 {
            assert!((co[c][k] - cs[c][k]).abs() < 0.03 * cs[c][c].max(cs[k][k]), "covariance {c},{k}: {} vs {}", co[c][k], cs[c][k]);
        }
    }
}

#[test]
fn deterministic_strength_and_spec() {
    let dir = tempfile::tempdir().unwrap();
    let style_path = dir.path().join("style.png");
    save_png(&style_path, &style_image(64, 64)).unwrap();
    let content = content_image(90, 60);
    let s = from_spec("color", Some(&style_path), &StylizerOptions::default()).unwrap();
    let a = s.stylize(&content).unwrap();
    assert_eq!(a, s.stylize(&content).unwrap(), "not deterministic");
    assert!(a.mean_abs_diff(&content) > 0.05);
    let zero = from_spec("color", Some(&style_path), &StylizerOptions { strength: 0.0, ..Default::default() }).unwrap();
    assert!(zero.stylize(&content).unwrap().mean_abs_diff(&content) < 1e-5);
    let half = from_spec("color", Some(&style_path), &StylizerOptions { strength: 0.5, ..Default::default() }).unwrap();
    let h = half.stylize(&content).unwrap().mean_abs_diff(&content);
    assert!(h > 0.2 * a.mean_abs_diff(&content) && h < 0.8 * a.mean_abs_diff(&content), "{h}");
}

#[test]
fn flat_content_stays_finite() {
    let content = Image::filled(32, 32, [0.5, 0.5, 0.5]);
    let out = color_transfer(&content, &style_image(32, 32), 1.0);
    assert_finite_in_range(&out);
}
