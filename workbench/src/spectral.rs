//! The discrete Fourier transform the workbench needs: the report's residual spectrum and the
//! noise statistics of the fit (`residual::noise_energy_sd`).

/// In-place radix-2 FFT (length must be a power of two; other lengths are left unchanged).
/// Twiddles by a per-stage recurrence (one `sin_cos` per stage), so it is cheap enough to run
/// inside a shape search.
pub fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    if n < 2 || !n.is_power_of_two() || im.len() != n {
        return;
    }
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * std::f64::consts::PI / len as f64;
        let (ws, wc) = ang.sin_cos();
        let (mut c, mut s) = (1.0, 0.0);
        for k in 0..len / 2 {
            for start in (0..n).step_by(len) {
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * c - im[b] * s;
                let ti = re[b] * s + im[b] * c;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
            }
            (c, s) = (c * wc - s * ws, c * ws + s * wc);
        }
        len <<= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cosine on bin 3 of 16 lands on bins 3 and 13 with n/2 each; Parseval holds.
    #[test]
    fn fft_of_a_cosine_and_parseval() {
        let n = 16;
        let x: Vec<f64> = (0..n)
            .map(|i| (std::f64::consts::TAU * 3.0 * i as f64 / n as f64).cos())
            .collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; n]);
        fft(&mut re, &mut im);
        for k in 0..n {
            let mag = (re[k] * re[k] + im[k] * im[k]).sqrt();
            let want = if k == 3 || k == 13 { 8.0 } else { 0.0 };
            assert!((mag - want).abs() < 1e-9, "bin {k}: {mag}");
        }
        let e_t: f64 = x.iter().map(|v| v * v).sum();
        let e_f: f64 = re.iter().zip(&im).map(|(a, b)| a * a + b * b).sum::<f64>() / n as f64;
        assert!((e_t - e_f).abs() < 1e-9);
    }
}
