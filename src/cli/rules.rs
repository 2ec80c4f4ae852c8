//! `ogm-corners rules`: the rule table, as text pictures or CSV.

use clap::{Args, ValueEnum};

use ogm_corners::backend::rules::code_picture;
use ogm_corners::{Result, RuleTable};

use super::{write_stdout, RulesArg};

#[derive(Clone, Copy, Debug, ValueEnum)]
enum RulesFormat {
    Text,
    Csv,
}

#[derive(Args, Debug)]
pub(super) struct RulesArgs {
    /// Which reading of the paper's rules to print.
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// Output format: text with a picture of each code, or CSV `code,rule`.
    #[arg(long, value_enum, default_value = "text")]
    format: RulesFormat,
    /// Only one code per rotation class (the smallest), as pictured in docs/detectors.md.
    #[arg(long)]
    canonical: bool,
}

pub(super) fn run(a: RulesArgs) -> Result<()> {
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
