//! The separable Gaussian blur both the corner detector and the virtual rig's lens use: one
//! implementation, in `f64` (the detector takes second derivatives of the result, so it is not
//! quantised to bytes as `imageproc`'s blur is).

/// A normalised Gaussian kernel of standard deviation `sigma` (pixels), radius ⌈3σ⌉; `[1]` for
/// no blur (`sigma` ≤ 0 or not a number).
pub fn gaussian_kernel(sigma: f64) -> Vec<f64> {
    if !(sigma > 0.0) {
        return vec![1.0];
    }
    let r = (3.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = k.iter().sum();
    k.into_iter().map(|v| v / sum).collect()
}

/// Separable blur of a `w × h` image of `N`-channel pixels with a normalised odd kernel,
/// clamping at the borders.
///
/// # Panics
/// If `img` holds fewer than `w × h` pixels.
pub fn blur<const N: usize>(img: &[[f64; N]], w: usize, h: usize, kernel: &[f64]) -> Vec<[f64; N]> {
    assert!(img.len() >= w * h, "blur: {} pixels for {w}×{h}", img.len());
    let r = kernel.len() / 2;
    let pass = |src: &[[f64; N]], along_x: bool| {
        let mut out = vec![[0.0; N]; w * h];
        for v in 0..h {
            for u in 0..w {
                let mut acc = [0.0; N];
                for (j, k) in kernel.iter().enumerate() {
                    let i = if along_x {
                        v * w + (u + j).saturating_sub(r).min(w - 1)
                    } else {
                        (v + j).saturating_sub(r).min(h - 1) * w + u
                    };
                    for (a, s) in acc.iter_mut().zip(&src[i]) {
                        *a += k * s;
                    }
                }
                out[v * w + u] = acc;
            }
        }
        out
    };
    pass(&pass(img, true), false)
}
