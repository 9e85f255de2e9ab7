//! What the gap workflow recovers on the corpus' campaigns, and where it stops: the figures behind
//! the tolerances the `gap_hidden` tests assert, the causes found for what is left, and the
//! remedies tried that did not help (so they are not tried again). This module holds no code.
//!
//! # Known limits
//!
//! `texture-lowpass` cannot bring back the real pattern (it is not in the entry; see
//! [`texture`](super::texture)): once added, sample renders carry procedural detail of the missing
//! spectrum ([`crate::sensor::detail`]), which has zero mean, so the photometric RMS (against the
//! expected render) stays and the texture's band power against the real albedo's
//! ([`super::Metrics::texture_band_log_ratio`], the run's headline [`Figure`](super::Figure) then)
//! is what shrinks — on mini seeds 101 and 102 from −0.790 and −0.737 to −0.655 and −0.471, where
//! the same campaigns with a faithful texture read −0.691 and −0.618 (the detail's spectrum,
//! extrapolated from where the low-passed texture still shows its signal, overshoots on seed 102);
//! and the smallest level or contrast change the render names (an exposure; a response curve the
//! noise cannot decide) is about 5 DN RMS, because renders of laser DEMs are themselves a little
//! darker and flatter than the real images (a radial falloff cannot mimic that, so vignetting is
//! named from 3 DN²). Over a terrain's narrow intensity range a mild response curve and an exposure
//! look alike to the render: a curve of 1.18 is an offset of +0.06 within 2 DN, and exposures that
//! brighten with little offset (gains 1.11–1.14, mini seeds 106, 110, 112) had a lower held-out
//! error as curves of 1.10–1.24 from mini's two captures. The repeat frames' noise over the dark
//! background tells them apart whatever the entry ([`response`](super::response)): on mini seeds
//! 101–112 every hidden curve (1.18–2.39, and 1.10 and 1.06 set on seeds 101–103) is named within
//! 0.008 of the truth, every exposure whose black level the background shows reads a linear
//! response with its black level within 0.3 DN (its offset is then held there, and its gain, fitted
//! to the render, comes out within 0.8 %: seeds 103, 105, 106, 108, 110, 112), and nothing hidden
//! reads linear. The witness is silent without two frames per pose or a dark background, and
//! undecided when an exposure clips the background to 0 (offsets under about −3 DN: seeds 101, 104,
//! 107, 109, 111) or lifts it so far that the background's noise no longer shows the curve (+10.5
//! DN, seed 102); then the render decides as before, the dark background bounding an exposure's
//! black level from above ([`super::photometry::Samples::black_limit`]: an offset that lifts it is
//! a response curve in disguise), and the gains come out 3–8 % off.
//!
//! # How close the fitted parameters come
//!
//! Parameters are as good as the views are many and as wide as the scene they show. From mini's two
//! captures (four views) a vignetting strength comes out within 5 % alone and next to a response
//! curve or a pose bias (seeds 101–103: −0.4, −1.0, −4.3 %; next to a gamma, held at the curve the
//! noise shows, with a free gain, seeds 101–105: −0.5, −1.7, −3.8, +0.1, −1.0 %, where the curve
//! fitted to the render alone left +1.7 to +6.0 %; it was +8, −9, −23 % and +20 % before the stereo
//! overlap entered the fit), a distortion's displacement at 0.7 of the radius comes out −5.1 and
//! −1.6 % off on the test's seeds (101, 102: dk1 −0.0447 for −0.0466, 0.0391 for 0.0385, −4.1 and
//! +1.5 %, both radial terms fitted to the render and the stereo pairs together); over seeds
//! 101–105 dk1 −4.1, +1.6, +11.4, +15.8 and −1.1 % (seed 104: dk2 0.0017 for 0.0075 — the two terms
//! still trade off). With the laser texture's earlier principal-component incidence normal
//! (`merge.clean` v3) seeds 101–107 read −5.8, −1.5, +10.1, +9.0, 0.0, −1.0 and −10.3 % in the
//! displacement (dk1 −5.1, +1.7, +10.5, +15.4, −1.1, +12.3, −16.3 %). With one term it was −8.1,
//! −2.3, +12.8, +10.2, +14.7, −2.2 and +8.7 % (a hidden dk2 of 0.0075–0.0138 went into dk1; dk1 17
//! % off on average). From the render's samples alone it was −11.8, −10.7, +34.0, +9.2, +2.1, +24.7
//! and +5.6 %: the laser entry's render residual is lower at that fit than at the truth on every
//! seed checked (101, 102, 103, 106), its texture pulls; the stereo pairs
//! ([`super::geometry::stereo_pairs`]) do not see the texture. Nor is the entry's registration what
//! is left: the laser block of these campaigns is tilted by 0.13–0.19° against the ground frame (5
//! markers over 2 m), yet with that error removed by the truth (render samples alone) the test's
//! seeds still read −12 and −4 % in dk1, and the pose bias came out no closer. And a pose bias's
//! rotation and translation trade off (pitch against the vertical translation: seed 102, 0.46° for
//! 0.03° with 14 mm of y) while the displacement they make together at 1.5 m is within 3.2 and 6.7
//! mm (seeds 101, 102), over seeds 101–107 (principal-component incidence normal) within 2.4–6.7 mm
//! (mean 4.1), the roll within 0.03–0.15° (mean 0.084°), the rotation within 0.09–0.73° (mean
//! 0.33°). With the render's samples alone (the pairs out of a pose bias's fit) the same seeds read
//! 2.7–5.5 mm (mean 3.9), roll 0.02–0.30° (mean 0.116°), rotation 0.03–1.27° (mean 0.42°): the
//! pairs see the roll (it moves the right camera vertically about the left) and not a motion common
//! to both cameras; the test `gap_hidden` asserts these measured tolerances. Six capture locations
//! (`corpus generate --captures 6`) bring the displacement within 1.9 and 2.0 mm and the roll
//! within 0.070° and 0.066° (seeds 101, 102; asserted too) and narrow the trade-off without
//! removing it (seed 101: within 0.091° and 1.1 mm on every axis; seed 102: pitch 0.22° off with 6
//! mm of y): the terrain fills only the lower part of a mini view, where a pitch and a vertical
//! translation look alike at the terrain's distance. Where along that valley the fit stops is set
//! by the entry, not by the optimiser or the pairs' geometry. Given the campaign's true terrain
//! instead ([`run_on`](super::run_on); `gap_hidden` asserts it) the same fit recovers a pose bias
//! within 0.03° and 0.3 mm on every axis from two locations (seeds 101–104) and a distortion's
//! `dk1` within 3 % (seeds 101–104: −2.7, −0.3, 0.0, +1.1 %; the laser entry reads seeds 103, 104
//! +11 and +16 %). With nothing hidden (six locations, seed 103) the forced pose-bias fit (render
//! samples and pairs) reads 0.58° of pitch with 17 mm of y on the laser entry, 0.17° and 5 mm with
//! the laser heights under the true albedo, 0.17° and 5 mm with the true heights under the laser
//! texture, and 0.005° and 0.1 mm with both true. Of the entry's heights it is their border that
//! pulls, not their noise or resolution: 5 and 10 cm cut off the laser heightfield's edges took the
//! same fit to 0.41° and 0.23° (0.07° under the true albedo), while the true heights with 2 mm of
//! noise, blocked to 12 mm cells, tilted by the laser block's 0.09° or raised 2 mm stayed within
//! 0.04° (a raise comes out as the translation it is). The stereo pairs alone, through the laser
//! heights, go to 0.57° with 20 mm of y, the same on `laser/0.02` and `sfm/0.02`; through the true
//! heights to 0.05°. A hidden bias on the laser entry comes out shifted the same way (seeds
//! 101–104, six locations: pitch −0.09, +0.22, +0.50, +0.06° off, y 0.7, 6.0, 15.3, 4.0 mm), and
//! six locations do not settle `dk1` against `dk2` there either (seeds 101–107: +0.2, −16.1, +4.9,
//! −2.5, +1.7, +7.1, −9.5 %). The largest single pull was the survey markers (each capture looks at
//! one; see [`markers`](super::markers)): on seed 103 the 0.7 % of render samples within 4 cm of a
//! marker and the 2.6 % of pairs within 8 cm held all of the fit's preference for its solution over
//! the truth. Kept out, the same seeds read pitch −0.09, +0.14, +0.37, +0.01° off and y 1.7, 2.9,
//! 9.6, 0.7 mm (mean error over the six axes and four seeds 0.12° → 0.09° and 3.6 → 2.7 mm); a
//! distortion from two locations (seeds 101–107) `dk1` +3.9, −6.0, +8.4, +0.8, +8.5, +3.6, −22.9 %
//! (fitted / true − 1; with the markers: −4.1, +1.6, +11.4, +15.8, −1.1 % on 101–105). What still
//! pulls on seed 103 are the render's strongest band-pass features (1.8 % of the samples beyond 3
//! standard deviations) and the ground 5–20 cm inside the heightfield's border; squashing the
//! band-pass (`2·tanh(x/2)`), a Huber or Tukey weight from the fit's residuals, leaving out samples
//! next to the render's depth discontinuities, or leaving out the entry's small bumps (cells 4 mm
//! above the DEM smoothed at 2 cm, where most of the remaining pull on seed 103 sat: dark pebbles)
//! moved the seeds' errors by ±0.1° either way without shrinking them. Nor did comparing
//! something the texture's shading enters less: the band-pass's local energy (its square
//! blurred 3 px, square-rooted, both images; seeds 101–107) missed two of seven distortions and
//! left the pose bias's rotations up to 0.58° off; a render under a uniform albedo (shading
//! only) missed four of seven distortions and named the pose bias on one of the first five
//! seeds. It is the texture, not the
//! heights: under the true albedo the entry's own heights give a hidden bias within 0.10° and 2.9
//! mm on every axis from two locations (seeds 101–104; `gap_hidden` asserts 101, 102) and from six.
//! The texture's error against the true albedo (averaged over its 1 cm cells) sits on the relief —
//! RMS 0.14–0.20 on cells 2 mm or more off their 7 cm mean, 0.05 on the flat — where the laser's
//! reflectance keeps the shading of sub-cell facets toward each scanner (the incidence normal is
//! the 6 cm plane's). From six locations seed 103's pitch stays 0.36–0.38° off with the scan's
//! range noise off or its step 2.5 times finer (0.26° with both); in place of the texture, the true
//! albedo averaged over its cells reads 0.09°, and times such shading, blurred 8 mm, 0.16°.
//! Removing the relief from the masks instead loses the alignment's information (pitch up to
//! 0.58°); weighting the stereo pairs three times more moves the error into the vertical
//! translation (−4 to −7 mm). Nor is it the incidence correction's scale: with its normal window at
//! 12 cm instead of 6 seed 103's pitch reads 0.39° off, with no correction at all 0.43° (and an
//! exposure is named), and with a 3 cm window on a scan 2.5 times finer 0.52°. Leaving out what the
//! laser DEM interpolated (cells under TIN triangles longer than 2.5 times the median, and filled
//! holes, with two cells' margin: 2–4 % of a view's terrain pixels, most at its far end) took seed
//! 103's pitch from six locations to 0.17° and 5.9 mm, and the mean error over seeds 101–104 from
//! two locations from 0.154° and 4.5 mm to 0.131° and 3.6 mm, but seed 101's `dk1` went from 3.9 %
//! to 15.2 % off and seed 106's pose bias was no longer named: the far terrain holds the radial
//! lever arm and much of a pose's signal (without the margin, or with four cells, the same trade).
//! Nor is the reconstruction's entry closer: `sfm/0.02` (2 cm heights fitted to the SfM mesh, its
//! vertex colours the albedo blurred by 1 cm, without the laser's shading) gave from two locations
//! on seeds 101–104 a pose bias within the targets on 2, 2, 1 of four rotation axes and 3, 1, 3
//! translation axes, `dk1` within 5 % once (one distortion not named), and `texture-lowpass` named
//! next to a distortion, a pose bias and nothing hidden (its colours are blurrier than the laser's
//! 1 cm texture).
//!
//! What loosened the texture's hold is a witness that compares real with real across
//! captures ([`super::geometry::cross_pairs`]): a bias fixed to the rig moves the views of two
//! captures against each other, where the two cameras of one capture move together and their
//! pairs see it only through the depth it changes. Each view is band-passed at the scale the
//! terrain has in it (the same ground band: at one fixed pixel band two captures disagree,
//! 1.15 in unit-variance units on seed 101 with nothing hidden; matched, 0.04–0.44 at the
//! refined pose), and each group of pairs is weighted by its residual at the joint fit. From mini's two
//! captures (seeds 101–114, a pose bias alone) the six axes came within ±0.1° / ±3 mm on 65 of
//! 84 — rotations about the rig's x, y, z on 13, 7 and 9 of 14, translations on 11, 12 and 13 —
//! where the render's samples and the stereo pairs had 33 (2, 6, 10; 7, 2, 6); seed 103's
//! pitch, 0.42° off before, 0.07°. Weighted at the render's own fit only, 35 of 42 on seeds
//! 101–107 (37 reweighted); pairing only where the local map between the views is nearly
//! isotropic (axes within 1.25 or 2 of each other, its scale from the render's depth) lowered
//! their residual but lost axes (31 and 33 of 42). What is left is mostly the rotation about
//! the rig's vertical (seed 101: 0.31° off, traded against 7.9 mm of x), and twice the
//! reported errors cover the axes' errors on 77 of 84. From six locations every axis is within
//! the targets (seeds 101–104; worst −0.071°/−2.2 mm, −0.014°/+0.7 mm, +0.078°/−1.7 mm,
//! −0.068°/−1.6 mm; `gap_hidden` asserts 101, 102), where before those pairs seed 102's pitch
//! read 0.14° off (the survey markers kept out) and seed 103's 0.36–0.38° (above).
//! A distortion's `dk1` is not helped the same way (seeds 101–107 +2.4, +1.8, +16.3, 0.0,
//! −8.0, +26.8, +1.8 %; within 5 % on 5 of 14 over 101–114, where 3 of 7 on 101–107 were
//! before): the trade-off with `dk2` sets the stopping point. Nothing hidden (101–107) still
//! names nothing, and a hidden texture low-pass no geometric effect. Pairing each two views of
//! different captures both ways (the samples of either view's grid, not only the lower one's)
//! lost: seeds 101–104 had 13 axes off the targets against 5 (seed 103's six axes all but
//! one). Nor does scaling the cross-capture pairs' inverse-variance weight help: doubled,
//! seeds 101–106 had 19 axes off against 5 (seed 103's bias no longer named); halved, seeds
//! 101–107 had 12 off against 5. The residuals at the hidden bias, on the first pass (mean
//! squares of the stereo / cross-capture pairs, each run against its own joint fit), show
//! that the pairs' own minimum lies off the truth: they prefer the fit on the laser entry by
//! 5–12 % (seed 112: 0.0287 / 0.1303 at the fit, 0.0301 / 0.1368 at the truth; 101: 0.0078 /
//! 0.2163 against 0.0087 / 0.2413; seed 109's cross-capture pairs and seed 104's, on target,
//! within 1 %), under the true albedo on the entry's heights by 2–9 % (112: 0.0291 / 0.1344;
//! 101: 0.0080 / 0.2286), on the true terrain by 0.4–1.4 % (112: 0.0279 / 0.1248 against
//! 0.0280 / 0.1254; 101: 0.0069 against 0.0070) but for seed 101's cross-capture pairs (0.1802
//! against 0.1937). What pulls them is what they share with the render: the points, placed by
//! the depth of the render at the uncorrected pose — its heights (the entry's smooth more
//! than the truth) and its occlusions (which the render's samples cannot follow either: on the
//! true terrain they prefer the first pass's fit too, 0.1172 against 0.1388 on seed 112,
//! which is why the bias is refined from a corrected render).
//!
//! An exact Jacobian of the alignment residuals (the Catmull–Rom interpolant's gradient through
//! the projection, the distortion and the bias; it matched central differences to 10⁻⁵) in
//! place of the forward differences did not make the fits faster: estec seed 2's geometric
//! stage took 667 s against 679, and its pose bias came out farther off (rotation about x
//! 0.035° off against 0.012°). An exact Jacobian costs about a third of the six to eight
//! residual evaluations a forward-difference one does, so the fits must have taken more
//! iterations (not counted): the forward difference's step averages over a residual this
//! rough, the exact gradient does not. It was not kept. Where a run's time goes (`perf`, mini
//! seed 101, a pose bias: 17 s, 13 of them in the geometric stage): the alignment residuals
//! 55 % (sampling and projecting), the renders 24 %. The Gaussian passes behind every
//! band-pass had taken another 24 % before they summed a line at a time (bit-identical,
//! `bench_blur`: 2.8–5.2× faster), and a stage rendered again a model the one before had
//! rendered (now handed back): that run 20.6 → 17.2 → 15.4 s, estec seed
//! 2's pose bias 776 → 734 → 669 s (geometric stage 670 → 647 → 608 s, photometric 20 → 6 s,
//! texture 21 → 8 s, the final measurement 23 → 9 s), with nothing hidden 264 → 201 s (peak
//! memory 3.0 → 3.3 GB: the kept renders), every figure the same.
//!
//! Why the pairs stop where they do: two captures related by a screw motion (the rover turns
//! about a near-vertical axis between them) cannot see a bias that is itself a rotation about
//! that axis with a shift along it — it moves both captures' views alike, so real still
//! matches real. On seeds 101–114 that two-dimensional family held 36–99 % (median 87 %) of
//! each fitted bias's error, rotations taken at 1.5 m, and 95–99 % on the three worst seeds
//! (101, 109, 112; `tools/gap/weak_plane.py`); only the entry decided it. Neither refining the
//! pose a second time from a render at the refined pose (18 axes off against 19) nor placing the
//! pairs' points on the campaign's true heights (20 off; worst rotation 0.17° against 0.31°;
//! with the pairs weighted three times more, 21) closed it. The survey markers did: each ball
//! in view, sighted in the real frames by a Lambertian sphere of its radius under the campaign
//! light ([`markers::sight`](super::markers::sight); 0.17 / 0.14 px RMS from the true poses'
//! projections, mini seed 11), joins the geometric fit as a ground control point. Seeds
//! 101–114, a pose bias alone, two captures: every one of the 84 axes within ±0.1° / ±3 mm
//! (mean error 0.023° and 0.59 mm, worst 0.083° and 2.1 mm; 65 of 84 before).
//!
//! In a distortion's fit, sighted through the calibration alone, they moved `dk1` on the laser
//! entry within 5 % on 7 of 14 seeds (5 before) but pulled it off where the render is right:
//! on the true terrain seeds 101, 102 read −22.7 and +11.4 % against −2.7 and −0.3 %. Two
//! causes, each measured. The sphere modelled without the distortion reads the shape the
//! distortion gives a ball off the image centre as a shift (0.28 px in the unit test, 0.016
//! through the lens); so a distortion's balls are now sighted through the distortion fitted
//! without them, and the fit repeated with them. And each ball's sightings lay 0.1–0.3 px
//! off even through the true camera from the true pose, the same in both cameras (seed 102:
//! the right and left views of one ball +0.25 px in y both; the Vicon mean is within 0.01 px
//! of the true centre): the corpus stamped a ball into its height grid of 2.5–5 mm cells, a
//! faceted cap the sphere matches to a fraction of a millimetre only. Against a render that
//! is right, those errors outweighed the field: weighted as through the entry, the true
//! terrain's `dk1` read −9.6 and +14.3 %; with the weight scaled by the render's mean squared
//! residual −3.2 and −1.0 %. On the laser entry (seeds 101–114): 7 of 14 within 5 %, mean
//! error 5.9 %, worst 11.7 %, against 5 of 14, 9.1 % and 26.8 % without the sightings. The
//! corpus now renders its balls in the captures as exact spheres (`render::Sphere`; the caps
//! stay in the grid the laser scans): the same seeds' `dk1` came within 5 % on 11 of 14, mean
//! error 3.3 %, worst +10.7 % (0.0, +8.6, +2.4, +0.6, −0.9, +10.7, +4.6, −0.8, +3.0, +2.2,
//! +4.4, −0.5, +6.5, −0.6 %), the displacement at 0.7 of the image radius within 3.4 % (mean 0.9 %); the
//! true terrain's −2.8 and −1.0 %; a pose bias's 84 axes all on target (mean 0.021° and 0.47
//! mm). Part of what remained was the fit's own: it samples a render made through the
//! calibration, on the calibration's pixel grid, against real frames taken (and band-passed)
//! through the distortion, and on the true terrain of seed 113 it read `dk1` +8.6 % off
//! where the re-rendered residual was lower at the truth (0.0060 against 0.0068 at the fit).
//! Refined once from a render made through the fitted distortion (as a pose bias already was),
//! the true terrain's read +3.0 %, and the laser entry's `dk1` came within 5 % on 12 of 14
//! seeds, mean error 2.0 %, worst +9.9 % (−1.1, +5.7, +1.1, 0.0, 0.0, +9.9, +2.4, −1.7, +0.2,
//! +1.4, +1.4, +0.7, +1.9, −0.8 %), the displacement within 2.8 % (mean 1.0 %). What
//! remains is the entry's: its heights pull both captures alike (seed 106 on the entry's
//! heights with the true albedo +13.2 %, on the true terrain +3.3 %, before the
//! refinement), and with them the precision of the dk1–dk2 split: from two capture
//! locations the reported σ of `dk1` is 7–15 % of it. From four locations the same seeds'
//! `dk1` came within 5 % on 14 of 14, mean error 1.4 %, worst 3.9 % (−2.4, +1.0, 0.0, +3.9,
//! +0.3, −0.8, 0.0, −2.5, −0.6, +1.9, +1.6, −0.5, −3.0, −0.6 %), every error within twice
//! the reported σ (seeds 102 and 106 from +5.7 and +9.9 % to +1.0 and −0.8 %). Through
//! one camera (cross-capture pairs only) the dozen sightings traded `dk1` against `dk2`
//! (seed 102, balls as caps: +23.8 %, `dk2` −0.028 for +0.001, against −15.7 % without), so a
//! distortion takes them only where stereo pairs hold the second term.
//!
//! # The estec preset
//!
//! From estec's eight captures a hidden vignetting of 0.4756 came out 0.4775 ± 0.0008 and a pose
//! bias within 0.041° and 0.4 mm per axis (seed 2; 0.049° and 0.8 mm with the survey markers kept
//! out; 0.026° and 1.1 mm from the render's samples alone, before the rig-frame bias and the
//! pairs; with the cross-capture pairs (0.1653°, 0.1812°, 0.4400°; 6.8, −12.6, 19.0 mm)
//! came out within 0.016° and 0.6 mm, where the build before them read 0.049° and 0.9
//! mm — at a cost: the geometric stage took 670 s against 488 s and the run's peak memory was
//! 6.3 GB against 4.2 GB, the scaled band-passes of sixteen views at two levels; with the
//! survey markers' sightings, 20 of them, 6.80 → 0.23 px RMS, within 0.016° and 0.45 mm:
//! −0.009°, −0.016°, +0.005°; +0.45, −0.20, −0.08 mm, each within its reported error — before
//! the sightings were gated by the ball's image radius and an 8-bit contrast, far balls of
//! 1.5–2.4 px sighted up to 4 px off kept the bias from being named at all), a hidden distortion (dk1 −0.0417, dk2 0.0056) came out dk1 −0.0397 ± 0.0004, dk2 0.0034
//! ± 0.0004 (−5.0 % in dk1, displacement at 0.7 of the radius −2.6 %; stereo residual 0.187 →
//! 0.017; with one radial term −0.0370, −5.0 % in the displacement; with the survey markers'
//! sightings joined, 25 of them, 6.32 → 0.26 px RMS, −0.0409 and 0.0045: −2.0 % in dk1,
//! −0.8 % in the displacement, named alone; with the balls rendered as spheres in the
//! captures, 23 sightings, 5.57 → 0.16 px RMS, −0.0409 and 0.0046 ± 0.0016 and 0.0035:
//! −2.0 % and −0.9 %, the run 11.5 min on two cores, 5.0 GB peak; refined once from a render
//! made through the fit, −0.0410 ± 0.0011 and 0.0048 ± 0.0022: −1.7 % in dk1, −0.8 % in the
//! displacement, the run 14.1 min, 7.5 GB peak while the refinement's scaled band-passes
//! lived beside the first pass's; with the jackknife and the per-capture fits made before the
//! refinement and the first pass's dropped, the same result at 5.8 GB peak), and nothing
//! hidden named nothing. A hidden texture low-pass of 27.5 mm came out 24.1 ± 4.1 mm, alone; before the
//! rig-frame bias and the stereo pairs a false pose bias (28 mm along the optical axis) was named
//! next to it (the band-pass alignment, with the texture low-passed, sees mostly relief shading).
//! It is no longer chosen because its held-out drop, 0.034, is under the geometric floor (0.04) —
//! not because the pairs rejected it.
//!
//! The photometric effects alone (seed 2): a response curve of 2.0333 came out 2.0317 ± 0.0016
//! (from the repeat frames' noise), the photometric RMS 64.7 → 12.6 DN against 13.6 with
//! nothing hidden; an exposure of gain 0.7372 and offset −0.0437 (it clips the background)
//! 0.7583 ± 0.0216 and −0.0521 ± 0.0060 (+2.9 % and −2.1 DN; 33.9 → 10.2 DN); a noise of
//! shot gain 0.0997 and read σ 2.83 DN 0.0963 and 2.87 DN (the spectrum's RMS log ratio
//! 0.470 → 0.085); each alone, nothing else named. A run takes 4.5 min on two cores, 2.6 of
//! them in the geometric stage, which finds nothing there.
//!
//! A hidden blur of 0.963 px (seed 2) came out 0.968 ± 0.054 px, nothing else named (13 531
//! skyline profiles; the widths' quadrature difference would have read 0.995). The run takes
//! 6 min 6 s on two cores, the blur stage 14 s of it (80 s while the profiles were sampled one
//! after another, and again for each capture left out).
//!
//! Hidden shadows (seed 2, a light recorded 3.4° and 1.3° off) came out 5.95° / 18.2° ± 1.1° /
//! 0.7° for a true 6.83° / 18.00°, nothing else named. That run takes 10 min on two cores, the
//! shadows stage 5 of them: the search renders sixteen 1280 × 1024 views under some 30 lights,
//! and each capture's leave-one-out search again. Tracing each view's camera rays once and
//! shading them under each light ([`crate::render::Scene::relight`], 0.41 of a shadowed render's
//! time in `bench_render`), and keeping the search's shadowed images for the fold searches,
//! which walk the same directions from the record, took it from 36 min (32 in the stage) with
//! the same result to the byte.
//!
//! # A lone camera
//!
//! Through one camera alone (`gap --cameras navcam_left`, as for a rover with one NavCam: no stereo
//! pairs, its two captures paired with each other, the camera its own rig frame)
//! seeds 101, 102 read a distortion's displacement −1.3 and −4.3 % off (dk1 −6.0 and −1.6 %,
//! both terms; −7.9 and −3.7 %, dk1 −14.8 and +0.5 %, before the fit was refined from a render
//! made through it), a pose bias's displacement 3.1 and 6.3 mm off, and nothing hidden named
//! nothing (asserted by `gap_hidden`). Over seeds 101–107 every case is named right, but
//! without the pairs the texture pulls the distortion again (displacement −15.0 to +39.4 % off,
//! before the refinement) and the roll is looser (up to 0.27° off; displacement 2.6–6.4 mm).
