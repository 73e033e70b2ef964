//! Named random streams.
//!
//! Every draw comes from its own ChaCha stream keyed by (seed, purpose, index), so adding a draw
//! to one purpose never shifts another: the plant of a seed is the same whatever the family,
//! the excitation or the record length.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;
use rand_distr::StandardNormal;

/// SplitMix64 finaliser: a bijective 64-bit mixer.
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// FNV-1a of a purpose tag.
fn tag_hash(tag: &str) -> u64 {
    tag.bytes().fold(0xCBF2_9CE4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// The stream for one purpose of one seed.
pub fn stream(seed: u64, tag: &str, index: u64) -> Draw {
    let mut h = mix(mix(seed) ^ tag_hash(tag));
    h = mix(h ^ index.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    let mut key = [0u8; 32];
    for chunk in key.chunks_exact_mut(8) {
        h = mix(h);
        chunk.copy_from_slice(&h.to_le_bytes());
    }
    Draw(ChaCha12Rng::from_seed(key))
}

/// A random stream with the few distributions a physicist asks for.
#[derive(Debug, Clone)]
pub struct Draw(ChaCha12Rng);

impl Draw {
    /// Uniform on [a, b).
    pub fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.0.random::<f64>()
    }
    /// Log-uniform on [a, b): "over a decade" means this.
    pub fn log_uniform(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.0.random::<f64>()).exp()
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        self.0.sample(StandardNormal)
    }
    /// ±1 with equal odds.
    pub fn sign(&mut self) -> f64 {
        if self.0.random::<bool>() {
            1.0
        } else {
            -1.0
        }
    }
    /// A raw 64-bit word.
    pub fn word(&mut self) -> u64 {
        self.0.random::<u64>()
    }
    /// `n` independent standard normals.
    pub fn normals(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.normal()).collect()
    }
}
