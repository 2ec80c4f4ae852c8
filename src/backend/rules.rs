//! The rule table of the OGM corner detector, derived once from the paper's formulas.
//!
//! A free centre pixel C has neighbours
//! ```text
//! Q  B  P
//! A' C  A
//! P' B' Q'
//! ```
//! Its 8-neighbour code has bit i set when neighbour i is occupied, clockwise from the top-left:
//! bit0 Q, bit1 B, bit2 P, bit3 A, bit4 Q', bit5 B', bit6 P', bit7 A'. The paper states each rule for one
//! orientation; a code is accepted when any of its four 90-degree rotations satisfies a rule.

use std::fmt;

/// Offsets (dx, dy) of the neighbours in bit order, y down: Q, B, P, A, Q', B', P', A'.
pub const NEIGHBOUR_OFFSETS: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
    (-1, 0),
];

/// Which reading of the paper's garbled "mod(...) = 0" to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum RuleSet {
    /// "mod 3 = 0": each group of three cells is empty or full. Accepts 44 codes. The default.
    #[default]
    Paper,
    /// "mod 2 = 0": each group holds an even number of occupied cells. Accepts 36 codes.
    PaperMod2,
}

impl RuleSet {
    /// The modulus of the reading.
    pub fn modulus(self) -> u32 {
        match self {
            RuleSet::Paper => 3,
            RuleSet::PaperMod2 => 2,
        }
    }

    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            RuleSet::Paper => "paper",
            RuleSet::PaperMod2 => "paper-mod2",
        }
    }
}

impl fmt::Display for RuleSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The code after turning the neighbourhood `quarter_turns` times by 90 degrees clockwise.
pub fn rotate_code(code: u8, quarter_turns: u32) -> u8 {
    // Turning clockwise moves each neighbour two places along the clockwise ring.
    code.rotate_left(2 * (quarter_turns % 4))
}

/// The code of the neighbourhood mirrored left to right (x -> -x): Q<->P, A<->A', Q'<->P'.
pub fn mirror_code(code: u8) -> u8 {
    (0..8).fold(0u8, |m, i| {
        let j = (10 - i) % 8; // bit i goes to bit (2 - i) mod 8
        m | (((code >> i) & 1) << j)
    })
}

/// The paper's three rules for one orientation; returns the rule (4, 5 or 6) that accepts `code`.
pub fn canonical_rule(code: u8, modulus: u32) -> Option<u8> {
    let n = |i: u32| u32::from((code >> i) & 1);
    let (q, b, p, a, q2, b2, p2, a2) = (n(0), n(1), n(2), n(3), n(4), n(5), n(6), n(7));
    let r_s = a + a2 + b + b2;
    let r_2 = p + p2;
    let r_4 = q + q2;
    let r_d = r_2 + r_4;
    let r = r_s + r_d;
    let r_sup = p + b + q;
    let r_der = p + a + q2;
    let r_inf = p2 + b2 + q2;
    let r_esq_p = a + p + b;
    match r {
        4 if r_esq_p % modulus == 0 && r_s == 2 && r_sup + r_inf == 3 && r_2 != r_4 => Some(4),
        5 if r_s == 2 && (r_sup + r_der) % modulus == 0 => Some(5),
        6 if r_s == 3 && r_d == 3 => Some(6),
        _ => None,
    }
}

/// For each of the 256 neighbour codes, the rule that accepts it (4, 5 or 6) or 0.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RuleTable {
    set: RuleSet,
    rules: [u8; 256],
}

impl RuleTable {
    /// Derives the table from the formulas and the four rotations.
    pub fn new(set: RuleSet) -> Self {
        let mut rules = [0u8; 256];
        for (code, slot) in rules.iter_mut().enumerate() {
            *slot = (0..4)
                .find_map(|k| canonical_rule(rotate_code(code as u8, k), set.modulus()))
                .unwrap_or(0);
        }
        RuleTable { set, rules }
    }

    /// The reading this table was derived from.
    pub fn rule_set(&self) -> RuleSet {
        self.set
    }

    /// The rule that accepts `code`, or `None`.
    #[inline]
    pub fn rule(&self, code: u8) -> Option<u8> {
        match self.rules[code as usize] {
            0 => None,
            r => Some(r),
        }
    }

    /// The raw table: entry `code` is 4, 5, 6 or 0 (for upload to other backends).
    pub fn as_bytes(&self) -> &[u8; 256] {
        &self.rules
    }

    /// The accepted codes in increasing order, with their rules.
    pub fn accepted(&self) -> impl Iterator<Item = (u8, u8)> + '_ {
        (0..=255u8).filter_map(|c| self.rule(c).map(|r| (c, r)))
    }

    /// Fewest blocking neighbours among the accepted codes (set bits), or `None` when no code is accepted:
    /// a pixel with fewer cannot be a keypoint, which lets the bit-plane paths skip almost every word.
    pub fn min_accepted_bits(&self) -> Option<u32> {
        self.accepted().map(|(c, _)| c.count_ones()).min()
    }

    /// One accepted code per rotation class (the smallest code of the class), with its rule.
    pub fn canonical(&self) -> Vec<(u8, u8)> {
        self.accepted()
            .filter(|&(c, _)| (1..4).all(|k| rotate_code(c, k) >= c))
            .collect()
    }
}

/// A 3-line picture of a neighbour code: `#` occupied, `.` not occupied, `C` the free centre.
pub fn code_picture(code: u8) -> [String; 3] {
    let mut grid = [['.'; 3]; 3];
    grid[1][1] = 'C';
    for (i, (dx, dy)) in NEIGHBOUR_OFFSETS.iter().enumerate() {
        if (code >> i) & 1 == 1 {
            grid[(dy + 1) as usize][(dx + 1) as usize] = '#';
        }
    }
    grid.map(|row| {
        row.iter()
            .map(|c| c.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    })
}
