use crate::common::*;
use physfit_track::*;

#[test]
#[ignore]
fn debug_crossing() {
    let truth = crate::crossing::ballistic(100, 512.0, 6.0, 3.0, 200, 42);
    let dir = TempDir::new("dbgx");
    render_to(&truth, &issue_settings(512, 512, 5.0, 9), dir.path());
    let out = track(
        dir.path(),
        &TrackOptions {
            named_start: Some(truth.named_start()),
            ..TrackOptions::default()
        },
    );
    let mut last_bad = std::collections::HashSet::new();
    for p in &out.table.points {
        let i: usize = p.particle[1..].parse().unwrap();
        let t = truth.frames[p.frame][i];
        let e = (p.x - t.x).hypot(p.y - t.y);
        if e > 1.0 && last_bad.insert(p.particle.clone()) {
            let near: Vec<_> = truth.frames[p.frame]
                .iter()
                .enumerate()
                .filter(|(j, q)| *j != i && (*q - t).norm() < 15.0)
                .map(|(j, q)| (j, ((q - t).norm() * 10.0).round() / 10.0))
                .collect();
            println!(
                "frame {} {} flag {:?} err {:.2} near {:?}",
                p.frame, p.particle, p.flag, e, near
            );
            for f in p.frame.saturating_sub(3)..=p.frame {
                let pts: Vec<_> = out
                    .table
                    .points
                    .iter()
                    .filter(|q| {
                        q.frame == f
                            && (q.particle == p.particle
                                || near.iter().any(|(j, _)| q.particle == format!("p{j}")))
                    })
                    .map(|q| {
                        (
                            q.particle.clone(),
                            (q.x * 10.0).round() / 10.0,
                            (q.y * 10.0).round() / 10.0,
                            q.flag,
                            q.mass.round(),
                        )
                    })
                    .collect();
                let tr: Vec<_> = std::iter::once(i)
                    .chain(near.iter().map(|(j, _)| *j))
                    .map(|j| {
                        (
                            j,
                            (truth.frames[f][j].x * 10.0).round() / 10.0,
                            (truth.frames[f][j].y * 10.0).round() / 10.0,
                        )
                    })
                    .collect();
                println!("   f{f}: tracks {:?}\n        truth {:?}", pts, tr);
            }
        }
    }
}

#[test]
#[ignore]
fn debug_crossing_errors() {
    let truth = crate::crossing::ballistic(100, 512.0, 6.0, 3.0, 200, 42);
    let dir = TempDir::new("dbgx2");
    render_to(&truth, &issue_settings(512, 512, 5.0, 9), dir.path());
    let out = track(
        dir.path(),
        &TrackOptions {
            named_start: Some(truth.named_start()),
            ..TrackOptions::default()
        },
    );
    let mut big = std::collections::BTreeMap::new();
    let mut hist = [0usize; 6];
    for p in &out.table.points {
        let i: usize = p.particle[1..].parse().unwrap();
        let t = truth.frames[p.frame][i];
        let e = (p.x - t.x).hypot(p.y - t.y);
        hist[(e.floor() as usize).min(5)] += 1;
        if e > 3.0 {
            big.entry(p.particle.clone()).or_insert_with(Vec::new).push((
                p.frame,
                (e * 10.0).round() / 10.0,
                p.flag,
            ));
        }
    }
    println!("error histogram by px: {hist:?}");
    for (k, v) in big {
        println!("{k}: {:?}", v);
    }
    for a in out
        .stats
        .ambiguities
        .iter()
        .filter(|a| a.kind != AmbiguityKind::Merged)
    {
        println!("{a}");
    }
}
