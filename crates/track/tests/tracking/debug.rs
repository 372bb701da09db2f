use crate::common::*;
use physfit_model::{simulate, RenderSettings};
use physfit_track::*;

#[test]
#[ignore]
fn debug_radius() {
    for (file, noise) in [("paper3.toml", 0.0), ("paper5.toml", 5.0)] {
        let scene = load_scene(file);
        let model = scene.model().unwrap();
        let rec = simulate(
            &model,
            &scene.initial_state(),
            &scene.integration_parameters(),
            10,
        );
        let settings = RenderSettings {
            noise,
            ..scene.render.clone()
        };
        let frames: Vec<Frame> = (0..5)
            .map(|k| frame_from_image(&physfit_render::render_frame(rec.frame(k), &settings, k)))
            .collect();
        let bg = estimate_background(&frames, BackgroundChoice::Auto);
        let f0 = &frames[0];
        for y in 278..287 {
            println!(
                "{:?}",
                (148..158)
                    .map(|x| f0.data[y * 512 + x] as i32)
                    .collect::<Vec<_>>()
            );
        }
        println!(
            "{file}: level {:?} noise {} dir {:?}",
            bg.level, bg.noise_sigma, bg.direction
        );
        for radius in [3.0, 4.0, 5.0] {
            let p = DetectParameters {
                radius,
                noise_sigma: bg.noise_sigma,
                expected_area: None,
            };
            let sig = bg.signal(&frames[0]);
            let b = find_blobs(&sig, 512, 512, &p);
            let seeds: Vec<[f64; 2]> = b.blobs.iter().map(|b| [b.x as f64, b.y as f64]).collect();
            let d = refine_centroids(
                &sig,
                512,
                512,
                &seeds,
                &vec![0.0; seeds.len()],
                radius + 1.0,
                bg.noise_sigma,
            );
            println!(
                "  radius {radius}: {} blobs; {:?}",
                b.blobs.len(),
                d.iter()
                    .take(12)
                    .map(|d| (
                        d.x.round(),
                        d.y.round(),
                        (d.size * 100.0).round() / 100.0,
                        d.mass.round()
                    ))
                    .collect::<Vec<_>>()
            );
        }
    }
}
