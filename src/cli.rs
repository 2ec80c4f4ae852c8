//! The `ogm-corners` command line.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Parser, Subcommand, ValueEnum};

use ogm_corners::output::{self, Format};
use ogm_corners::overlay;
use ogm_corners::rules::{code_picture, RuleTable};
use ogm_corners::synth;
use ogm_corners::{DetectOptions, Detector, Error, OccupancyMap, Result, RuleSet};

/// Finds corners in robot occupancy grid maps with the OGM corner detector.
#[derive(Parser, Debug)]
#[command(name = "ogm-corners", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Detect corners in a map (a ROS map_server .yaml, or a PGM/PNG image).
    Detect(DetectArgs),
    /// Generate a synthetic office map, detect its corners, write map, overlay and keypoints.
    Demo(DemoArgs),
    /// Print the rule table: the accepted 8-neighbour codes and the rule that accepts each.
    Rules(RulesArgs),
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum RulesArg {
    /// The paper's "mod(...) = 0" read as mod 3 (44 codes).
    Paper,
    /// The same read as mod 2 (36 codes).
    PaperMod2,
}

impl From<RulesArg> for RuleSet {
    fn from(r: RulesArg) -> Self {
        match r {
            RulesArg::Paper => RuleSet::Paper,
            RulesArg::PaperMod2 => RuleSet::PaperMod2,
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum BackendArg {
    /// The CPU reference implementation.
    Cpu,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum FormatArg {
    Csv,
    Json,
}

#[derive(Args, Debug)]
struct DetectOpts {
    /// Which reading of the paper's rules to use.
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// Count unknown neighbours as occupied.
    #[arg(long)]
    unknown_as_occupied: bool,
    /// Where to run the detector.
    #[arg(long, value_enum, default_value = "cpu")]
    backend: BackendArg,
}

impl DetectOpts {
    fn options(&self) -> DetectOptions {
        DetectOptions {
            rules: self.rules.into(),
            unknown_as_occupied: self.unknown_as_occupied,
        }
    }

    fn detector(&self) -> Detector {
        match self.backend {
            BackendArg::Cpu => Detector::new(self.options()),
        }
    }
}

#[derive(Args, Debug)]
struct DetectArgs {
    /// The map: a ROS .yaml (loads its image too) or a PGM/PNG image (ROS default thresholds).
    map: PathBuf,
    #[command(flatten)]
    opts: DetectOpts,
    /// Output format.
    #[arg(long, value_enum, default_value = "csv")]
    format: FormatArg,
    /// Write the keypoints to FILE instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Also write a PNG of the map with the keypoints marked.
    #[arg(long, value_name = "PNG")]
    overlay: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct DemoArgs {
    /// Output folder.
    #[arg(short, long, value_name = "DIR", default_value = "demo-out")]
    output: PathBuf,
    /// Map size, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "1024x768", value_parser = parse_size)]
    size: (u32, u32),
    /// Seed of the synthetic map.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    opts: DetectOpts,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum RulesFormat {
    Text,
    Csv,
}

#[derive(Args, Debug)]
struct RulesArgs {
    /// Which reading of the paper's rules to print.
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// Output format: text with a picture of each code, or CSV `code,rule`.
    #[arg(long, value_enum, default_value = "text")]
    format: RulesFormat,
    /// Only one code per rotation class (the smallest), as pictured in the README.
    #[arg(long)]
    canonical: bool,
}

/// Parses `WIDTHxHEIGHT`.
fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got `{s}`"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("bad width `{w}`"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("bad height `{h}`"))?;
    if w == 0 || h == 0 {
        return Err(format!("zero-size map {w}x{h}"));
    }
    Ok((w, h))
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Detect(a) => detect(a),
        Command::Demo(a) => demo(a),
        Command::Rules(a) => rules(a),
    }
}

fn detect(a: DetectArgs) -> Result<()> {
    let map = OccupancyMap::load(&a.map)?;
    for w in &map.warnings {
        eprintln!("ogm-corners: warning: {w}");
    }
    let mut detector = a.opts.detector();
    let det = detector.detect(&map)?;
    let format = match a.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Json => Format::Json,
    };
    let options = detector.options();
    let backend = detector.backend_name();
    let write = |out: &mut dyn Write| {
        output::write_keypoints(out, format, &map, &det, &options, &backend)?;
        out.flush()
    };
    match &a.output {
        Some(path) => {
            let file = fs::File::create(path).map_err(|e| Error::output(path, e))?;
            write(&mut BufWriter::new(file)).map_err(|e| Error::output(path, e))?;
        }
        None => write_stdout(write)?,
    }
    if let Some(png) = &a.overlay {
        overlay::write_overlay(png, &map.image, &det.keypoints)?;
    }
    Ok(())
}

/// Writes to standard output; a closed pipe (`| head`) ends quietly rather than as an error.
fn write_stdout(f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    match f(&mut out) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Error::output("<stdout>", e)),
    }
}

fn demo(a: DemoArgs) -> Result<()> {
    let (w, h) = a.size;
    let dir = &a.output;
    fs::create_dir_all(dir).map_err(|e| Error::output(dir, e))?;
    let image = synth::office_map(w, h, a.seed)?;
    let pgm = dir.join("demo-map.pgm");
    let yaml = dir.join("demo-map.yaml");
    image.write_pgm(&pgm)?;
    let yaml_text = format!(
        "# Synthetic office map made by `ogm-corners demo --size {w}x{h} --seed {}`\n\
         image: demo-map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n\
         occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n",
        a.seed
    );
    fs::write(&yaml, yaml_text).map_err(|e| Error::output(&yaml, e))?;
    // Load it back as a user's map would be, so the demo runs the whole path.
    let map = OccupancyMap::load(&yaml)?;
    let mut detector = a.opts.detector();
    let start = Instant::now();
    let det = detector.detect(&map)?;
    let elapsed = start.elapsed();
    let csv = dir.join("keypoints.csv");
    let json = dir.join("keypoints.json");
    let overlay_png = dir.join("overlay.png");
    let options = detector.options();
    let backend = detector.backend_name();
    for (path, format) in [(&csv, Format::Csv), (&json, Format::Json)] {
        let file = fs::File::create(path).map_err(|e| Error::output(path, e))?;
        let mut out = BufWriter::new(file);
        output::write_keypoints(&mut out, format, &map, &det, &options, &backend)
            .and_then(|_| out.flush())
            .map_err(|e| Error::output(path, e))?;
    }
    overlay::write_overlay(&overlay_png, &map.image, &det.keypoints)?;
    let mpx = w as f64 * h as f64 / 1e6;
    let secs = elapsed.as_secs_f64();
    println!(
        "{} corners in a {w}x{h} synthetic office map ({mpx:.2} Mpx) in {:.2} ms on {} ({:.0} Mpx/s)",
        det.keypoints.len(),
        secs * 1e3,
        backend,
        mpx / secs.max(1e-9)
    );
    for p in [&yaml, &pgm, &overlay_png, &csv, &json] {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn rules(a: RulesArgs) -> Result<()> {
    let table = RuleTable::new(a.rules.into());
    let codes = if a.canonical {
        table.canonical()
    } else {
        table.accepted().collect()
    };
    write_stdout(|out| {
        match a.format {
            RulesFormat::Csv => {
                writeln!(out, "code,rule")?;
                for (c, r) in &codes {
                    writeln!(out, "{c},{r}")?;
                }
            }
            RulesFormat::Text => {
                writeln!(
                    out,
                    "# rules {}: {} codes{}; bit0 Q (top-left), clockwise to bit7 A' (left); # occupied",
                    table.rule_set(),
                    codes.len(),
                    if a.canonical {
                        " (one per rotation class)"
                    } else {
                        ""
                    }
                )?;
                for (c, r) in &codes {
                    let pic = code_picture(*c);
                    writeln!(out, "\ncode {c:3} (0b{c:08b})  rule {r}")?;
                    for line in pic {
                        writeln!(out, "    {line}")?;
                    }
                }
            }
        }
        out.flush()
    })
}

/// Exit status for an error that reached the top.
pub fn exit_code(e: &Error) -> i32 {
    e.exit_code()
}
