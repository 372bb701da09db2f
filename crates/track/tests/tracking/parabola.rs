//! A least-squares parabola through a free flight, shared by the tracker's and the
//! pipeline's real-recording tests (the latter include this file by path).

/// Least-squares `y = c0 + c1 t + c2 t^2`: the coefficients and the RMS residual.
pub fn parabola(t: &[f64], y: &[f64]) -> ([f64; 3], f64) {
    let a = nalgebra::DMatrix::from_fn(t.len(), 3, |i, j| t[i].powi(j as i32));
    let y = nalgebra::DVector::from_column_slice(y);
    let c = a
        .clone()
        .svd(true, true)
        .solve(&y, 1e-12)
        .expect("a parabola through the arc");
    let rms = ((&a * &c - y).norm_squared() / t.len() as f64).sqrt();
    ([c[0], c[1], c[2]], rms)
}
