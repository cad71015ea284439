//! Image metrics: PSNR and SSIM (Wang et al. 2004: 11x11 Gaussian window, σ = 1.5,
//! K1 = 0.01, K2 = 0.03, on RGB in [0,1], averaged over channels), as used by NeRF papers.

/// PSNR in dB between two RGB float images in [0,1] (same length).
pub fn psnr(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    let mse: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    mse_to_psnr(mse)
}

/// PSNR of an MSE on [0,1] colours, capped at 120 dB for a perfect fit. A non-finite MSE
/// (a diverged field) stays NaN: it must never read as a perfect score.
pub fn mse_to_psnr(mse: f64) -> f64 {
    if !mse.is_finite() {
        return f64::NAN;
    }
    -10.0 * mse.max(1e-12).log10()
}

fn gaussian_kernel() -> [f64; 11] {
    let mut k = [0.0f64; 11];
    let mut s = 0.0;
    for (i, v) in k.iter_mut().enumerate() {
        let x = i as f64 - 5.0;
        *v = (-x * x / (2.0 * 1.5 * 1.5)).exp();
        s += *v;
    }
    k.map(|v| v / s)
}

/// Separable Gaussian filter with "valid" borders: output is (w-10) x (h-10).
fn filter(img: &[f64], w: usize, h: usize) -> Vec<f64> {
    let k = gaussian_kernel();
    let (ow, oh) = (w - 10, h - 10);
    let mut tmp = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            tmp[y * ow + x] = (0..11).map(|i| k[i] * img[y * w + x + i]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..11).map(|i| k[i] * tmp[(y + i) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM of two RGB images (w x h x 3, values in [0,1]). Images smaller than the window
/// fall back to a single global window.
pub fn ssim(a: &[f32], b: &[f32], w: usize, h: usize) -> f64 {
    assert_eq!(a.len(), w * h * 3);
    assert_eq!(b.len(), w * h * 3);
    let (c1, c2) = (0.01f64 * 0.01, 0.03f64 * 0.03);
    let mut total = 0.0;
    for ch in 0..3 {
        let x: Vec<f64> = (0..w * h).map(|i| a[i * 3 + ch] as f64).collect();
        let y: Vec<f64> = (0..w * h).map(|i| b[i * 3 + ch] as f64).collect();
        if w < 11 || h < 11 {
            let n = (w * h) as f64;
            let mx = x.iter().sum::<f64>() / n;
            let my = y.iter().sum::<f64>() / n;
            let vx = x.iter().map(|v| (v - mx).powi(2)).sum::<f64>() / n;
            let vy = y.iter().map(|v| (v - my).powi(2)).sum::<f64>() / n;
            let cxy = x.iter().zip(&y).map(|(p, q)| (p - mx) * (q - my)).sum::<f64>() / n;
            total += ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
            continue;
        }
        let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
        let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
        let xy: Vec<f64> = x.iter().zip(&y).map(|(p, q)| p * q).collect();
        let (mx, my) = (filter(&x, w, h), filter(&y, w, h));
        let (sxx, syy, sxy) = (filter(&xx, w, h), filter(&yy, w, h), filter(&xy, w, h));
        let mut s = 0.0;
        for i in 0..mx.len() {
            let (m1, m2) = (mx[i], my[i]);
            let v1 = sxx[i] - m1 * m1;
            let v2 = syy[i] - m2 * m2;
            let cov = sxy[i] - m1 * m2;
            s += ((2.0 * m1 * m2 + c1) * (2.0 * cov + c2)) / ((m1 * m1 + m2 * m2 + c1) * (v1 + v2 + c2));
        }
        total += s / mx.len() as f64;
    }
    total / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_score_perfectly() {
        let img: Vec<f32> = (0..32 * 24 * 3).map(|i| ((i * 37) % 101) as f32 / 100.0).collect();
        assert!((ssim(&img, &img, 32, 24) - 1.0).abs() < 1e-9);
        assert!(psnr(&img, &img) > 100.0);
    }

    #[test]
    fn noise_lowers_ssim_and_psnr_matches_definition() {
        let a: Vec<f32> = (0..32 * 32 * 3).map(|i| ((i / 3) % 32) as f32 / 32.0).collect();
        let b: Vec<f32> = a.iter().enumerate().map(|(i, v)| v + if i % 2 == 0 { 0.1 } else { -0.1 }).collect();
        // every pixel off by 0.1 -> MSE 0.01 -> 20 dB
        assert!((psnr(&a, &b) - 20.0).abs() < 1e-4);
        let s = ssim(&a, &b, 32, 32);
        assert!(s < 0.9 && s > 0.0, "ssim {s}");
    }
}
