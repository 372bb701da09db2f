//! Unit tests of the blob detector.

use super::blob::{BlobSize, DetectParameters};
use super::box_filter::{box_means, prefix_sums};
use super::find::{find_blobs, find_blobs_forming, visible_fraction, Scratch, CHUNK};
use super::labels::Labels;
use super::peaks::{above_bits, above_bits_portable, RowTest};
use super::regions::{Fill, Regions};

fn disc_image(w: usize, h: usize, centres: &[(f64, f64)], r: f64, amp: f32) -> Vec<f32> {
    let mut img = vec![0.0f32; w * h];
    for &(cx, cy) in centres {
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                img[y * w + x] += amp * (r + 0.5 - d).clamp(0.0, 1.0) as f32;
            }
        }
    }
    img
}

/// The span flood fill claims what the pixel-by-pixel one does (each claimed pixel
/// claiming its unclaimed 8-neighbours at or above the level): the same pixels, area
/// and border flag, on random images of several densities and sizes, with regions
/// grown one after another (each seeing the pixels the earlier ones took), seeds below
/// the level included, and every other region capped at a few pixels.
#[test]
fn span_flood_fill_matches_a_pixel_flood_fill() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for (w, h) in [(1usize, 1usize), (1, 9), (9, 1), (17, 13), (64, 48)] {
        for density in [0.2, 0.5, 0.7, 1.0] {
            let image: Vec<f32> = (0..w * h)
                .map(|_| if rng.gen::<f64>() < density { 1.0 } else { 0.0 })
                .collect();
            let (mut spans, mut pixels) = (Regions::default(), Regions::default());
            spans.reset(w * h);
            pixels.reset(w * h);
            for k in 0..8 {
                let seed = rng.gen_range(0..w * h);
                let cap = if k % 2 == 0 { usize::MAX } else { 5 };
                if pixels.region_at(seed).is_some() {
                    assert!(
                        spans.region_at(seed).is_some(),
                        "{w}x{h}: pixel {seed} claimed by one fill only"
                    );
                    continue;
                }
                let fill = Fill {
                    image: &image,
                    width: w,
                    height: h,
                    level: 0.5,
                    cap,
                };
                let r = spans.grow(&fill, seed);
                let want = pixels.grow_pixels(&fill, seed);
                let of = |regions: &Regions, r: usize| -> Vec<usize> {
                    (0..w * h).filter(|&q| regions.region_at(q) == Some(r)).collect()
                };
                let what = format!("{w}x{h} density {density} cap {cap}, seed {seed}");
                assert_eq!(of(&spans, r), of(&pixels, want), "{what}: pixels");
                assert_eq!(spans.area[r], pixels.area[want], "{what}: area");
                assert_eq!(spans.border[r], pixels.border[want], "{what}: border flag");
            }
        }
    }
}

/// A row's runs above its thresholds, found from bit masks 64 pixels at a time, are the
/// runs a pixel-by-pixel scan finds: rows shorter and longer than one mask, runs that
/// cross a mask's edge or reach the row's end, values equal to their threshold (not
/// above it). The SSE2 mask equals the portable one.
#[test]
fn row_runs_match_a_pixel_scan() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for width in [1usize, 5, 63, 64, 65, 130, 200, 512] {
        for density in [0.05, 0.5, 0.95, 1.0] {
            let thresholds: Vec<f32> = (0..width).map(|_| rng.gen_range(1.0..2.0)).collect();
            let line: Vec<f32> = thresholds
                .iter()
                .map(|&t| match rng.gen::<f64>() {
                    p if p < 0.1 => t,
                    p if p < density => t + 0.5,
                    _ => t - 0.5,
                })
                .collect();
            let mut want = Vec::new();
            let mut x = 0;
            while x < width {
                if line[x] > thresholds[x] {
                    let s = x;
                    while x < width && line[x] > thresholds[x] {
                        x += 1;
                    }
                    want.push((s as u32, x as u32));
                }
                x += 1;
            }
            let mut labels = Labels::default();
            labels.begin();
            labels.push_row(0, &line, &thresholds);
            let got: Vec<(u32, u32)> = labels.runs.iter().map(|r| (r.0, r.1)).collect();
            assert_eq!(got, want, "width {width}, density {density}");
            for x0 in (0..width).step_by(64) {
                let end = (x0 + 64).min(width);
                let (l, t) = (&line[x0..end], &thresholds[x0..end]);
                assert_eq!(
                    above_bits(l, t),
                    above_bits_portable(l, t),
                    "width {width} at {x0}"
                );
            }
        }
    }
}

/// The row pre-test of a chunk, four pixels at a time, passes exactly the pixels the
/// pixel-by-pixel test passes: plateaus (equal neighbours), values equal to the peak
/// threshold or to the mask, at every chunk of rows shorter and longer than a chunk.
#[test]
fn row_candidates_match_the_pixel_test() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for width in [1usize, 16, 17, 33, 100, 512] {
        for _ in 0..20 {
            // Few distinct levels, so that neighbours are often equal.
            let band: Vec<f32> = (0..width).map(|_| f32::from(rng.gen_range(0u8..6))).collect();
            let small: Vec<f32> = (0..width).map(|_| f32::from(rng.gen_range(0u8..4))).collect();
            let fy = 1.0 + f32::from(rng.gen_range(0u8..2));
            let mask: Vec<f32> = (0..width)
                .map(|_| f32::from(rng.gen_range(1u8..3)) * fy)
                .collect();
            let test = RowTest {
                band: &band,
                small: &small,
                mask: &mask,
                peak_min: 2.0,
            };
            for x0 in (0..width).step_by(CHUNK) {
                let x1 = (x0 + CHUNK).min(width);
                let want = test.candidates_portable(x0, x1);
                assert_eq!(test.candidates(x0, x1), want, "width {width} at {x0}");
                for x in x0..x1 {
                    let v = band[x];
                    let pass = v > 2.0
                        && small[x] > mask[x]
                        && (x == 0 || band[x - 1] < v)
                        && (x + 1 == width || band[x + 1] <= v);
                    assert_eq!(want >> (x - x0) & 1 == 1, pass, "width {width} at {x}");
                }
            }
        }
    }
}

#[test]
fn prefix_sums_match_a_running_sum_and_wrap() {
    for n in [0usize, 1, 3, 4, 5, 8, 9, 12, 17, 512] {
        let col: Vec<i32> = (0..n)
            .map(|i| ((i as i64 * 7_919 % 2_001) - 1_000) as i32 * 1_000_003)
            .collect();
        let mut pre = vec![7; n + 1];
        prefix_sums(&col, &mut pre);
        let mut s = 0i32;
        assert_eq!(pre[0], 0);
        for (i, c) in col.iter().enumerate() {
            s = s.wrapping_add(*c);
            assert_eq!(pre[i + 1], s, "n {n} at {i}");
        }
    }
}

/// The mean of `img` (`w` x `h`) over the box of half-width `half` about `(x, y)`, the
/// pixels outside the image left out, summed in double precision.
fn brute_box_mean(img: &[f32], w: usize, h: usize, half: usize, x: usize, y: usize) -> f64 {
    let (mut s, mut n) = (0.0f64, 0.0);
    for yy in y.saturating_sub(half)..=(y + half).min(h - 1) {
        for xx in x.saturating_sub(half)..=(x + half).min(w - 1) {
            s += f64::from(img[yy * w + xx]);
            n += 1.0;
        }
    }
    s / n
}

#[test]
fn box_means_of_a_signed_fractional_signal() {
    let (w, h) = (37, 23);
    let img: Vec<f32> = (0..w * h)
        .map(|i| (((i * 7_919) % 1_000) as f32 - 500.0) * 0.417)
        .collect();
    for (out, half) in box_means(&img, w, h, [3, 7]).iter().zip([3, 7]) {
        for y in 0..h {
            for x in 0..w {
                let want = brute_box_mean(&img, w, h, half, x, y);
                assert!(
                    (f64::from(out[y * w + x]) - want).abs() < 1e-3,
                    "half {half} at {x},{y}"
                );
            }
        }
    }
}

#[test]
fn visible_fraction_of_a_disc_at_the_border() {
    assert!((visible_fraction(50.0, 50.0, 4.0, 100, 100) - 1.0).abs() < 1e-12);
    // Centred on the frame's edge (x = -0.5): half the disc.
    assert!((visible_fraction(-0.5, 50.0, 4.0, 100, 100) - 0.5).abs() < 0.03);
    // In a corner: a quarter.
    assert!((visible_fraction(-0.5, -0.5, 4.0, 100, 100) - 0.25).abs() < 0.03);
}

#[test]
fn box_mean_matches_brute_force_at_borders() {
    let (w, h) = (9, 7);
    let img: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
    for halves in [[2, 5], [1, 3], [4, 12]] {
        for (out, half) in box_means(&img, w, h, halves).iter().zip(halves) {
            for y in 0..h {
                for x in 0..w {
                    let want = brute_box_mean(&img, w, h, half, x, y);
                    // Fixed point rounds each pixel to 1/8192 of a level.
                    assert!(
                        (f64::from(out[y * w + x]) - want).abs() < 2e-4,
                        "half {half} at {x},{y}"
                    );
                }
            }
        }
    }
}

/// The loops compiled for AVX2 give the baseline's box means and blobs to the bit, on
/// widths that leave every remainder of eight lanes.
#[test]
fn avx2_loops_give_the_baseline_values() {
    for (w, h) in [(97usize, 61usize), (64, 40), (131, 23)] {
        let mut img = disc_image(
            w,
            h,
            &[(20.0, 15.0), (26.5, 16.0), (w as f64 - 9.5, 12.25)],
            4.0,
            150.0,
        );
        for (i, v) in img.iter_mut().enumerate() {
            *v += ((i * 7_919) % 17) as f32 * 0.37 - 3.0;
        }
        let means = || box_means(&img, w, h, [3, 7]);
        let p = DetectParameters {
            radius: 4.0,
            noise_sigma: 2.5,
            expected: None,
        };
        let (wide, base) = (means(), crate::cpu::baseline_only(means));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&wide[0]), bits(&base[0]), "{w}x{h}");
        assert_eq!(bits(&wide[1]), bits(&base[1]), "{w}x{h}");
        let blobs = find_blobs(&img, w, h, &p);
        assert!(blobs.blobs.len() >= 2, "{blobs:?}");
        let baseline = crate::cpu::baseline_only(|| find_blobs(&img, w, h, &p));
        assert_eq!(format!("{blobs:?}"), format!("{baseline:?}"));
    }
}

/// Formed row by row as the filters ask, the signal gives the blobs of the whole image
/// formed first, and ends up whole; each row is asked for once, in order.
#[test]
fn a_signal_formed_row_by_row_gives_the_same_blobs() {
    let (w, h) = (97, 61);
    let mut img = disc_image(
        w,
        h,
        &[(20.0, 20.0), (27.5, 21.0), (60.5, 50.25), (3.0, 58.0)],
        4.0,
        120.0,
    );
    for (i, v) in img.iter_mut().enumerate() {
        *v += ((i * 7_919) % 13) as f32 - 6.0;
    }
    let p = DetectParameters {
        radius: 4.0,
        noise_sigma: 3.7,
        expected: None,
    };
    let want = find_blobs(&img, w, h, &p);
    assert!(want.blobs.len() >= 3, "{want:?}");
    let mut signal = vec![f32::NAN; w * h];
    let mut asked = Vec::new();
    let got = find_blobs_forming(&mut signal, w, h, &p, &mut Scratch::default(), |pixels, out| {
        asked.push(pixels.start / w);
        out.copy_from_slice(&img[pixels]);
    });
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
    assert_eq!(asked, (0..h).collect::<Vec<_>>());
    assert!(signal == img);
}

#[test]
fn finds_touching_discs_and_rejects_a_large_object() {
    let (w, h) = (120, 80);
    let mut img = disc_image(w, h, &[(20.0, 20.0), (28.0, 20.0), (60.5, 50.25)], 4.0, 200.0);
    for y in 40..75 {
        for x in 85..115 {
            img[y * w + x] += 150.0;
        }
    }
    let mut p = DetectParameters {
        radius: 4.0,
        noise_sigma: 1.0,
        expected: None,
    };
    let all = find_blobs(&img, w, h, &p);
    let single = all.blobs.iter().find(|b| b.x.abs_diff(60) <= 1).unwrap();
    p.expected = Some(BlobSize {
        area: single.area,
        extent: single.extent,
    });
    let set = find_blobs(&img, w, h, &p);
    let mut found: Vec<(usize, usize)> = set.blobs.iter().map(|b| (b.x, b.y)).collect();
    found.sort_unstable();
    assert_eq!(found.len(), 3, "{found:?}");
    for (f, t) in found.iter().zip([(20.0, 20.0), (28.0, 20.0), (60.5, 50.25)]) {
        assert!(
            (f.0 as f64 - t.0).abs() <= 1.0 && (f.1 as f64 - t.1).abs() <= 1.0,
            "{found:?}"
        );
    }
    assert!(set.too_large_count > 0);
}
