//! `preset:N` (multistyle26 via tract).

mod stylizer_support;

use snerf_stylize::stylizer::{from_spec, StylizerOptions};
use stylizer_support::{assert_finite_in_range, content_image, models_or_skip};

#[test]
fn two_presets_differ_and_keep_the_size() {
    let Some(opts) = models_or_skip("two_presets_differ_and_keep_the_size") else { return };
    // 101x67 is not a multiple of 4: padded and cropped back.
    let content = content_image(101, 67);
    let a = from_spec("preset:3", None, &opts).unwrap();
    let b = from_spec("preset:17", None, &opts).unwrap();
    assert_eq!(a.name(), "preset:3");
    let (oa, ob) = (a.stylize(&content).unwrap(), b.stylize(&content).unwrap());
    for o in [&oa, &ob] {
        assert_eq!((o.width, o.height), (101, 67));
        assert_finite_in_range(o);
        assert!(o.mean_abs_diff(&content) > 0.03, "preset output barely differs from content");
    }
    let d = oa.mean_abs_diff(&ob);
    assert!(d > 0.03, "presets 3 and 17 gave nearly the same image ({d})");
    // Deterministic.
    assert_eq!(a.stylize(&content).unwrap(), oa);
}

#[test]
fn strength_zero_is_the_content_and_half_is_between() {
    let Some(opts) = models_or_skip("strength_zero_is_the_content_and_half_is_between") else { return };
    let content = content_image(64, 48);
    let full = from_spec("preset:5", None, &opts).unwrap().stylize(&content).unwrap();
    let zero = from_spec("preset:5", None, &StylizerOptions { strength: 0.0, ..opts.clone() }).unwrap();
    assert_eq!(zero.stylize(&content).unwrap(), content);
    let half = from_spec("preset:5", None, &StylizerOptions { strength: 0.5, ..opts.clone() }).unwrap().stylize(&content).unwrap();
    let (dh, df) = (half.mean_abs_diff(&content), full.mean_abs_diff(&content));
    assert!((dh - 0.5 * df).abs() < 1e-3, "{dh} vs {df}");
}

#[test]
fn out_of_range_preset_is_refused() {
    let err = from_spec("preset:26", None, &StylizerOptions::default()).err().unwrap().to_string();
    assert!(err.contains("0..26"), "{err}");
}
