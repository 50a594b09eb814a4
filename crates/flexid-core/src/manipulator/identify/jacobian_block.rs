//! `J^T J` from Jacobian rows gathered in blocks: a row at a time, the upper triangle's
//! `P (P + 1) / 2` multiply-adds per row run as scalar updates of scattered sums; gathered
//! (transposed: each parameter's column of the block contiguous) they become
//! `P (P + 1) / 2` dot products of [`ROWS`] contiguous values, which vectorise (compiled
//! for AVX2 where the CPU has it: a product's four partial sums in one register instead of
//! two; no fused multiply-adds, so every build gives the same bits).

/// Rows per block.
pub const ROWS: usize = 64;

/// The gathered rows of one normal-equation pass.
#[derive(Debug, Clone)]
pub(super) struct JacobianBlock {
    /// Parameters `P`.
    np: usize,
    /// Rows gathered so far in this block.
    len: usize,
    /// Per parameter its column of the block (`P x ROWS`).
    cols: Vec<f64>,
}

impl JacobianBlock {
    pub(super) fn new(np: usize) -> Self {
        JacobianBlock {
            np,
            len: 0,
            cols: vec![0.0; np * ROWS],
        }
    }

    /// Forgets the rows gathered.
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds `row` (`P` values); a full block goes into the upper triangle of `jtj`
    /// (`P x P` row-major).
    pub(super) fn push(&mut self, row: &[f64], jtj: &mut [f64]) {
        for (c, &x) in self.cols.chunks_exact_mut(ROWS).zip(row) {
            c[self.len] = x;
        }
        self.len += 1;
        if self.len == ROWS {
            self.flush(jtj);
        }
    }

    /// The rows gathered into the upper triangle of `jtj`, then forgotten.
    pub(super) fn flush(&mut self, jtj: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above)
            unsafe { self.flush_avx2(jtj) };
            return;
        }
        self.flush_here(jtj);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn flush_avx2(&mut self, jtj: &mut [f64]) {
        self.flush_here(jtj);
    }

    /// [`JacobianBlock::flush`] as compiled for any CPU.
    #[inline(always)]
    fn flush_here(&mut self, jtj: &mut [f64]) {
        let (np, len) = (self.np, self.len);
        if len == 0 {
            return;
        }
        for a in 0..np {
            let ca = &self.cols[a * ROWS..a * ROWS + len];
            for b in a..np {
                jtj[a * np + b] += dot(ca, &self.cols[b * ROWS..b * ROWS + len]);
            }
        }
        self.len = 0;
    }
}

/// `x . y` with four partial sums (so that it vectorises).
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in xc.zip(yc) {
        for i in 0..4 {
            acc[i] += a[i] * b[i];
        }
    }
    acc[0] + acc[1] + acc[2] + acc[3] + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blocked `J^T J` is the row-by-row one, for a row count across several blocks.
    #[test]
    fn blocks_give_the_plain_sum() {
        let np = 5;
        let rows: Vec<Vec<f64>> = (0..2 * ROWS + 7)
            .map(|k| {
                (0..np)
                    .map(|a| ((k * 7 + a * 3) % 11) as f64 - 5.0)
                    .collect()
            })
            .collect();
        let mut plain = vec![0.0; np * np];
        for r in &rows {
            for a in 0..np {
                for b in a..np {
                    plain[a * np + b] += r[a] * r[b];
                }
            }
        }
        let mut jtj = vec![0.0; np * np];
        let mut block = JacobianBlock::new(np);
        for r in &rows {
            block.push(r, &mut jtj);
        }
        block.flush(&mut jtj);
        assert_eq!(jtj, plain);
    }

    /// The AVX2 build of the products and the plain one give the same bits.
    #[test]
    fn every_build_gives_the_same_bits() {
        let np = 24;
        let mut block = JacobianBlock::new(np);
        for k in 0..ROWS - 3 {
            for (a, c) in block.cols.chunks_exact_mut(ROWS).enumerate() {
                c[k] = ((k * 31 + a * 17) as f64).sin();
            }
            block.len += 1;
        }
        let (mut avx, mut plain) = (vec![0.0; np * np], vec![0.0; np * np]);
        block.clone().flush(&mut avx);
        block.flush_here(&mut plain);
        assert_eq!(avx, plain);
    }
}
