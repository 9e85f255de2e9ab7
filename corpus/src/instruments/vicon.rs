//! Vicon Nexus trajectory exports of the static markers and of the rig balls.
//!
//! Layout exactly as formats.md §5 (a Nexus 2.16 "Trajectories" export): two leading blank
//! lines, the section name, the rate in Hz, the `Subject:Marker` name row with each name above
//! the first of its three columns, `Frame,Sub Frame,X,Y,Z,...`, the `mm` units row, then one row
//! per frame. Positions are the true centres in millimetres (Vicon frame = ground frame) plus
//! Gaussian jitter (σ 0.2 mm per axis). Frames start at a seeded crop offset (> 1). Gaps are
//! empty cells: a few isolated dropped frames per marker, and, in the static-marker file, one
//! marker occluded for a stretch of 20–30 % of the trial (always leaving it ≥ 60 % of frames).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::sink::push_fixed;

/// Vicon capture rate, Hz.
pub const RATE_HZ: u32 = 100;

/// One marker's samples, metres; `None` = gap.
pub type Track = Vec<Option<[f64; 3]>>;

/// Jittered samples of fixed points with gaps; `occlusion` adds one long occluded stretch.
pub fn tracks(
    centres: &[[f64; 3]],
    frames: usize,
    occlusion: bool,
    rng: &mut ChaCha8Rng,
) -> Vec<Track> {
    let jitter = Normal::new(0.0, 0.0002).ok();
    let occluded = if occlusion && !centres.is_empty() {
        Some(rng.gen_range(0..centres.len()))
    } else {
        None
    };
    let stretch_len = frames / 5 + rng.gen_range(0..=frames / 10);
    let stretch_start = rng.gen_range(0..=frames.saturating_sub(stretch_len));
    centres
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let dropped: Vec<usize> = (0..rng.gen_range(0..4))
                .map(|_| rng.gen_range(0..frames))
                .collect();
            (0..frames)
                .map(|f| {
                    let mut n = || jitter.map_or(0.0, |j| j.sample(rng));
                    let p = [c[0] + n(), c[1] + n(), c[2] + n()];
                    let hidden = dropped.contains(&f)
                        || (occluded == Some(i)
                            && (stretch_start..stretch_start + stretch_len).contains(&f));
                    (!hidden).then_some(p)
                })
                .collect()
        })
        .collect()
}

/// The Nexus CSV text of `tracks` named `subject:name`, first frame `first_frame`.
pub fn nexus_csv(subject: &str, names: &[&str], tracks: &[Track], first_frame: u32) -> String {
    let mut s = String::from("\n\nTrajectories\n");
    s.push_str(&format!("{RATE_HZ}\n"));
    // Name row: two leading cells, then each name above the first of its three columns.
    let mut name_row = String::from(",");
    for n in names {
        name_row.push_str(&format!(",{subject}:{n},,"));
    }
    s.push_str(&name_row);
    s.push('\n');
    s.push_str("Frame,Sub Frame");
    names.iter().for_each(|_| s.push_str(",X,Y,Z"));
    s.push_str("\n,");
    names.iter().for_each(|_| s.push_str(",mm,mm,mm"));
    s.push('\n');
    let frames = tracks.first().map_or(0, Vec::len);
    for f in 0..frames {
        s.push_str(&format!("{},0", first_frame as usize + f));
        for t in tracks {
            match t.get(f).copied().flatten() {
                Some(p) => {
                    for v in p {
                        s.push(',');
                        push_fixed(&mut s, v * 1000.0, 5);
                    }
                }
                None => s.push_str(",,,"),
            }
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn layout_matches_nexus_header_and_gaps_are_empty_cells() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let t = tracks(&[[1.0, 2.0, 3.0], [0.5, 0.25, 0.0]], 50, true, &mut rng);
        let text = nexus_csv("Testbed", &["Marker1", "Marker2"], &t, 101);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(&lines[..4], &["", "", "Trajectories", "100"]);
        assert_eq!(lines[4], ",,Testbed:Marker1,,,Testbed:Marker2,,");
        assert_eq!(lines[5], "Frame,Sub Frame,X,Y,Z,X,Y,Z");
        assert_eq!(lines[6], ",,mm,mm,mm,mm,mm,mm");
        assert!(lines[7].starts_with("101,0,"));
        assert_eq!(lines.len(), 7 + 50);
        for l in &lines[7..] {
            assert_eq!(l.split(',').count(), 8, "{l}");
        }
        let gaps = lines[7..].iter().filter(|l| l.contains(",,,")).count();
        assert!(
            gaps >= 10,
            "the occluded stretch shows as empty cells ({gaps})"
        );
        let x: f64 = lines[7]
            .split(',')
            .nth(2)
            .unwrap()
            .parse()
            .unwrap_or(1000.0);
        assert!((x - 1000.0).abs() < 1.5 || lines[7].split(',').nth(2) == Some(""));
    }
}
