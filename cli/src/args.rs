//! Command-line arguments (clap derive). Parsing only: `main.rs` dispatches to `commands/`.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

/// regolith — compile terrain surveys into a certified, versioned terrain database for
/// planetary-rover simulators, and measure how close simulation is to reality.
#[derive(Debug, Parser)]
#[command(name = "regolith", version, propagate_version = true)]
#[command(
    after_help = "Exit codes: 0 ok, 1 a check failed (validate, release, verify), 2 usage or input error.\n\
Format spec: format-spec/SPEC.md (regolith.db/1)."
)]
pub struct Cli {
    /// Print machine-readable JSON on stdout instead of the human summary (progress still goes
    /// to stderr).
    #[arg(long, global = true)]
    pub json: bool,
    /// Show no progress on stderr (errors are still printed).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// The command.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Compile a survey campaign into a new release.
    ///
    /// Reads the campaign folder (campaign.toml and the raw files it names), registers and
    /// merges the scans, builds DEMs, textures and meshes, aligns the SfM model and writes an
    /// immutable release. `--check` parses every referenced file and prints an inventory.
    Compile {
        /// The campaign folder (or its campaign.toml).
        campaign: PathBuf,
        /// The database to write into (created if absent): a folder, or an object-store URL
        /// (`s3://bucket/prefix`, `gs://…`, `az://…`; docs/object-storage.md).
        #[arg(long, required_unless_present = "check")]
        db: Option<PathBuf>,
        /// Release `name@version` (default: the campaign name @ 1.0.0).
        #[arg(long, value_name = "NAME@VERSION")]
        release: Option<String>,
        /// Parse every referenced file and print an inventory; write nothing.
        #[arg(long)]
        check: bool,
    },
    /// Certify terrain entries against the real captures.
    ///
    /// Re-renders every heightfield and mesh entry at every capture pose, measures feature
    /// repeatability against the real images and writes a certificate per entry; exit 1 unless
    /// every entry passes.
    Validate {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// The release (default: latest).
        #[arg(long, default_value = "latest")]
        release: String,
        /// Entries to validate (default: every heightfield and mesh entry); repeatable.
        #[arg(long)]
        entry: Vec<String>,
        /// Detectors (harris, fast, sift, surf, mser; default: all); repeatable.
        #[arg(long)]
        detector: Vec<String>,
        /// JSON file overriding thresholds (`epsilon_px`, `min_mean_ratio_to_ceiling`,
        /// `min_ratio_to_ceiling` (one number, or per detector `{"fast": 0.2}`),
        /// `min_repeatability`, `max_photometric_rms`,
        /// `min_high_band_log_ratio`; defaults and their calibration: validator/src/validate.rs).
        #[arg(long)]
        thresholds: Option<PathBuf>,
        /// Also write an offline HTML report (index.html + PNG figures) into this folder:
        /// real, rendered and difference images, keypoint overlays, repeatability curves,
        /// keypoint counts and spectra per view, and a summary per entry.
        #[arg(long, value_name = "DIR", conflicts_with_all = ["shard", "merge"])]
        report: Option<PathBuf>,
        /// Compute only shard I of N (1 ≤ I ≤ N) of the (entry, view) units and store each
        /// unit's result in the database (`units/` refs) instead of certificates; units
        /// already stored are skipped. Run every shard (anywhere), then `--merge`.
        #[arg(long, value_name = "I/N", conflicts_with = "merge")]
        shard: Option<crate::commands::Shard>,
        /// Combine the stored unit results of every shard into the certificates one process
        /// would write (byte-identical); fails naming the missing units if a shard has not run.
        #[arg(long)]
        merge: bool,
    },
    /// Name the sensor effects that separate renders from the real images.
    ///
    /// Finds where simulation and measurement disagree for one entry, names the missing
    /// effects (vignetting, blur, noise, gamma, exposure, shadows, distortion, pose-bias,
    /// texture-lowpass), fits them and shows the gap before/after; `--apply` writes the fitted
    /// sensor model into a child release.
    Gap {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// The release (default: latest).
        #[arg(long, default_value = "latest")]
        release: String,
        /// The terrain entry, e.g. `laser/0.01`.
        #[arg(long)]
        entry: String,
        /// Only these captures (comma-separated or repeated; default: all).
        #[arg(long, value_delimiter = ',')]
        captures: Vec<String>,
        /// Only these cameras, e.g. `navcam_left` (comma-separated or repeated; default: all).
        /// One camera of a stereo head is examined as a lone camera, without stereo pairs.
        #[arg(long, value_delimiter = ',')]
        cameras: Vec<String>,
        /// Write the fitted model into a new release whose parent is the examined one.
        #[arg(long)]
        apply: bool,
        /// Minimum share of a stage's held-out error an effect must explain to be named.
        #[arg(long, default_value_t = 0.10)]
        min_share: f64,
        /// Write an offline HTML report (index.html + PNG charts) into this folder.
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Make a negative control: an entry with its texture blurred.
    ///
    /// Writes the degraded copy into a child release; `validate` must fail it. For checking and
    /// calibrating the gate on your own campaign.
    Control {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// The release (default: latest).
        #[arg(long, default_value = "latest")]
        release: String,
        /// The heightfield entry to copy, e.g. `laser/0.01` (it must have a texture).
        #[arg(long)]
        entry: String,
        /// Gaussian blur of the texture, σ in metres on the ground.
        #[arg(long, value_name = "SIGMA_M")]
        texture_blur_m: f64,
    },
    /// Publish a release whose terrain entries passed validation.
    ///
    /// Refuses unless every terrain entry has a passing certificate for this release (run
    /// `regolith validate` first), or `--allow-uncertified` is given, which makes a child
    /// release recording `allow_uncertified: true` in its manifest and publishes that.
    Release {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// The release (`name@version`, ref or id).
        release: String,
        /// Mark it as published (`refs/published/<name>@<version>`).
        #[arg(long)]
        publish: bool,
        /// Publish even without passing certificates (recorded in the manifest).
        #[arg(long)]
        allow_uncertified: bool,
    },
    /// Run the validator's detectors and repeatability metric on your own images.
    Features {
        /// What to do.
        #[command(subcommand)]
        action: FeaturesAction,
    },
    /// Rehash every object of every release; exit 1 naming each corrupt or missing one.
    Verify {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
    },
    /// Show a database's releases, a release's entries, or one entry.
    Inspect {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// A release: `name@version`, `latest`, or an id (prefix of at least 6 hex digits).
        release: Option<String>,
        /// An entry name, e.g. `laser/0.015`.
        entry: Option<String>,
    },
    /// Write an entry as plain files with their metadata (never partially written).
    Export {
        /// The database folder (or object-store URL, e.g. `s3://bucket/terrain`).
        db: PathBuf,
        /// The release.
        release: String,
        /// The entry.
        entry: String,
        /// Output folder; must not exist yet or be empty.
        #[arg(long)]
        to: PathBuf,
        /// Also write an engine-specific heightfield variant.
        #[arg(long, value_enum)]
        profile: Option<Profile>,
    },
    /// Remove objects no release references (holds the database's write lock).
    ///
    /// On an object store, where there is no lock, unreachable objects younger than
    /// `--grace-seconds` are kept: they may belong to a release another writer is committing.
    Gc {
        /// The database folder (or object-store URL).
        db: PathBuf,
        /// Keep unreachable objects younger than this (default: 0 for a folder, which the
        /// write lock protects; 3600 for an object store).
        #[arg(long, value_name = "N")]
        grace_seconds: Option<u64>,
    },
    /// Generate synthetic campaigns with ground truth and hidden effects.
    Corpus {
        /// What to do.
        #[command(subcommand)]
        action: CorpusAction,
    },
    /// Compile, validate and examine the checked-in demo campaign.
    ///
    /// Runs the main job on `corpus/demo` and says where the outputs are.
    Demo {
        /// The demo campaign folder.
        #[arg(long, default_value = "corpus/demo")]
        campaign: PathBuf,
        /// Output folder (the database goes to `<out>/db`).
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
    },
    /// Print a shell completion script.
    ///
    /// e.g. `regolith completions bash > ~/.local/share/bash-completion/completions/regolith`.
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the man page regolith(1).
    ///
    /// e.g. `regolith manpage > ~/.local/share/man/man1/regolith.1`; with `--dir`, write it and
    /// one page per command (regolith-compile(1), ...) into a folder.
    Manpage {
        /// Write `regolith.1` and `regolith-<command>.1` for every command into this folder.
        #[arg(long, value_name = "DIR")]
        dir: Option<PathBuf>,
    },
}

/// Engine-specific export variants (SPEC.md §5.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Profile {
    /// Square 2^n+1 grid, 16-bit PNG, `<heightmap><size>` in the sidecar.
    Gazebo,
    /// Unreal landscape size, value 32768 = z 0, ZScale in the sidecar.
    Unreal,
}

/// `regolith corpus ...`
#[derive(Debug, Subcommand)]
pub enum CorpusAction {
    /// Write a campaign folder (real file formats) plus `truth/`.
    Generate {
        /// Preset: `estec` (8.69 x 8.605 m yard, 6 scans, 8 captures) or `mini` (2 x 2 m, seconds).
        #[arg(long, value_enum, default_value = "mini")]
        preset: PresetArg,
        /// Seed: the same seed gives byte-identical files.
        #[arg(long)]
        seed: u64,
        /// Full resolution (2.5 mm truth grid, the real 0.030° scan step).
        #[arg(long)]
        full: bool,
        /// Capture locations (default: the preset's, estec 8, mini 2). More captures pin the
        /// gap workflow's fitted parameters down more tightly.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=64))]
        captures: Option<u32>,
        /// Hidden effects, comma-separated: vignetting, blur, noise, gamma, exposure, shadows,
        /// distortion, pose-bias, texture-lowpass.
        #[arg(long, value_name = "E[,E...]")]
        hidden_effect: Option<String>,
        /// Override a hidden effect's parameter, e.g. `vignetting.strength=0.3` (repeatable).
        #[arg(long, value_name = "E.name=value")]
        effect_param: Vec<String>,
        /// An auto-exposing camera: each capture location's exposure gain is multiplied by
        /// `e^u`, `|u|` drawn in `[SPREAD/2, SPREAD]` per location, brighter and darker by
        /// turns (truth/hidden.json `capture_exposure`). 0: one exposure for every capture.
        #[arg(long, value_name = "SPREAD", default_value_t = 0.0)]
        auto_exposure: f64,
        /// Output folder (created; must be empty or absent).
        #[arg(long)]
        out: PathBuf,
        /// Who makes the NavCam frames: `mitsuba` (a physically based renderer in a lab hall,
        /// then the corpus's own camera; independent of the validator) or `model` (the
        /// validator's own renderer and sensor model: fast, for unit tests of the fitting code
        /// only — the inverse crime; recorded in truth/renderer.json).
        #[arg(long, value_enum, default_value = "mitsuba")]
        renderer: RendererArg,
        /// Render cache of `--renderer mitsuba`: renders found here are reused, missing ones
        /// are rendered (needs Mitsuba: tools/render/install.sh) and stored. Default
        /// `$REGOLITH_RENDER_CACHE`, else `~/.cache/regolith/renders`.
        #[arg(long, value_name = "DIR")]
        renders: Option<PathBuf>,
        /// Never run the renderer: every render must be in the cache (say which are missing).
        #[arg(long)]
        no_render: bool,
        /// Samples per canvas pixel of `--renderer mitsuba`.
        #[arg(long, value_name = "N", default_value_t = 128,
              value_parser = clap::value_parser!(u32).range(1..=65536))]
        spp: u32,
        /// Also write malformed variants of every input kind into this folder.
        #[arg(long, value_name = "DIR")]
        bad_inputs: Option<PathBuf>,
    },
}

/// Who makes a corpus campaign's NavCam frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RendererArg {
    /// Mitsuba 3 path tracing in a lab hall + the corpus's own camera model.
    Mitsuba,
    /// The validator's own renderer and sensor model (unit tests of the fitting code only).
    Model,
}

/// Corpus presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PresetArg {
    /// The ESTEC yard.
    Estec,
    /// A small patch for tests.
    Mini,
}

/// `regolith features ...`
#[derive(Debug, Subcommand)]
pub enum FeaturesAction {
    /// Detect keypoints in an image (PNG/TIFF/JPEG, converted to grey).
    Detect {
        /// The image.
        image: PathBuf,
        /// harris, fast, sift, surf or mser.
        #[arg(long, default_value = "sift")]
        detector: String,
    },
    /// Repeatability of a detector between two images of the same scene (ε curve 1-5 px).
    Repeat {
        /// First image.
        image_a: PathBuf,
        /// Second image.
        image_b: PathBuf,
        /// harris, fast, sift, surf or mser.
        #[arg(long, default_value = "sift")]
        detector: String,
        /// 3x3 homography mapping A pixels to B pixels: 9 numbers as text (the Oxford dataset's
        /// `H1to3p`), or an OpenCV FileStorage XML, YAML or JSON file holding one 3x3
        /// `opencv-matrix` (OpenCV's `samples/data/H1to3p.xml`).
        #[arg(long, conflicts_with = "same_pose")]
        homography: Option<PathBuf>,
        /// The images were taken from the same pose (identity mapping).
        #[arg(long)]
        same_pose: bool,
    },
}
