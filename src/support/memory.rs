//! A memory budget checked before allocating: commands estimate what they will allocate from the image
//! header and their options, and refuse (bad input, exit 2) with the estimate and the limit instead of
//! aborting half way.

use std::fmt;

use crate::support::error::{Error, Result};

/// The environment variable that sets the limit when `--max-memory` is not given.
pub const ENV_VAR: &str = "OGM_MAX_MEMORY";

/// Used when the machine's memory cannot be read.
const FALLBACK_LIMIT: u64 = 8 << 30;

/// How much memory one run may allocate, in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    limit: u64,
    /// Where the limit came from, for the message.
    origin: Origin,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Origin {
    Machine,
    Given,
}

impl Default for Budget {
    /// [`Budget::machine`].
    fn default() -> Self {
        Budget::machine()
    }
}

impl Budget {
    /// 80% of the machine's memory (the cgroup limit, or what this process's address space and data
    /// limits leave, when lower), leaving room for the rest of the system; 8 GiB when none can be read.
    pub fn machine() -> Self {
        // The machine's memory and its cgroup's limit are read once a process: reading them costs about
        // 90 us, which the Python package paid on every detection (a 0.1 ms call on a small map). The
        // process's own limit is a system call and is read every time (a test may lower it).
        static FILES: std::sync::OnceLock<[Option<u64>; 2]> = std::sync::OnceLock::new();
        let [physical, cgroup] = *FILES.get_or_init(|| [physical_memory(), cgroup_limit()]);
        let total = [physical, cgroup, process_limit()]
            .into_iter()
            .flatten()
            .min();
        Budget {
            limit: total.map_or(FALLBACK_LIMIT, |t| t / 5 * 4),
            origin: Origin::Machine,
        }
    }

    /// A limit given by the user.
    pub fn new(limit: u64) -> Self {
        Budget {
            limit,
            origin: Origin::Given,
        }
    }

    /// `--max-memory` when given, else the environment variable, else [`Budget::machine`].
    pub fn from_option(given: Option<u64>) -> Result<Self> {
        if let Some(b) = given {
            return Ok(Budget::new(b));
        }
        match std::env::var(ENV_VAR) {
            Ok(v) if !v.trim().is_empty() => parse_bytes(&v)
                .map(Budget::new)
                .map_err(|e| Error::invalid(format!("{ENV_VAR}: {e}"))),
            _ => Ok(Budget::machine()),
        }
    }

    /// The limit in bytes.
    pub fn limit(&self) -> u64 {
        self.limit
    }

    /// Fails, with the estimate and the limit, when `bytes` are over the limit.
    pub fn check(&self, what: impl fmt::Display, bytes: u64) -> Result<()> {
        if bytes <= self.limit {
            return Ok(());
        }
        let from = match self.origin {
            Origin::Machine => "80% of this machine's memory or of this process's limits",
            Origin::Given => "as given",
        };
        Err(Error::invalid(format!(
            "{what} needs about {} of memory, over the limit of {} ({from}); raise it with --max-memory \
             or {ENV_VAR} if the machine has room",
            Bytes(bytes),
            Bytes(self.limit)
        )))
    }
}

/// Bytes for people: `1.5 GiB`, `320 MiB`, `12 KiB`, `100 B`.
#[derive(Clone, Copy, Debug)]
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0 as f64;
        for (unit, size) in [
            ("TiB", 1u64 << 40),
            ("GiB", 1 << 30),
            ("MiB", 1 << 20),
            ("KiB", 1 << 10),
        ] {
            if self.0 >= size {
                return write!(f, "{:.1} {unit}", b / size as f64);
            }
        }
        write!(f, "{} B", self.0)
    }
}

/// Parses a size: a number of bytes with an optional unit K, M, G or T (powers of 1024; `KiB`, `KB`, `k`
/// and so on are read alike), e.g. `512M`, `16G`, `1.5g`, `1048576`.
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: f64 = num
        .parse()
        .map_err(|_| format!("expected a size such as 512M or 16G, got `{s}`"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "unknown size unit `{other}` in `{s}` (use K, M, G or T)"
            ))
        }
    };
    let v = n * (1u64 << shift) as f64;
    if !(v.is_finite() && v >= 1.0 && v < u64::MAX as f64) {
        return Err(format!("size `{s}` is out of range"));
    }
    Ok(v as u64)
}

/// What this process's address space and data segment limits (`ulimit -v`, `ulimit -d`: RLIMIT_AS,
/// RLIMIT_DATA) leave beyond what it already uses (VmSize, VmData of `/proc/self/status`), if either is
/// set: the lower binds.
fn process_limit() -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        use rustix::process::{getrlimit, Resource};
        let limits = [Resource::As, Resource::Data].map(|r| getrlimit(r).current);
        if limits.iter().all(Option::is_none) {
            // No limit (the usual case): no need to read what is in use (a file read, tens of us).
            return None;
        }
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        let used = |key: &str| -> u64 {
            status
                .lines()
                .find_map(|l| l.strip_prefix(key))
                .and_then(|v| v.split_whitespace().next()?.parse::<u64>().ok())
                .map_or(0, |kib| kib.saturating_mul(1024))
        };
        [(limits[0], used("VmSize:")), (limits[1], used("VmData:"))]
            .into_iter()
            .filter_map(|(limit, used)| Some(limit?.saturating_sub(used)))
            .min()
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Total physical memory (Linux `/proc/meminfo`).
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The memory limit of this process's cgroup, or of any cgroup above it (v2 `memory.max`, v1
/// `memory.limit_in_bytes`), if any: the lowest one binds. Read from this process's own cgroup (a systemd
/// unit's `MemoryMax=`, a container's limit), not only the root.
fn cgroup_limit() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").unwrap_or_default();
    let mut files = Vec::new();
    for line in own.lines() {
        let mut parts = line.splitn(3, ':');
        let (_, controllers, path) = (parts.next(), parts.next(), parts.next());
        let (Some(controllers), Some(path)) = (controllers, path) else {
            continue;
        };
        let (root, file) = match controllers {
            "" => ("/sys/fs/cgroup", "memory.max"),
            c if c.split(',').any(|c| c == "memory") => {
                ("/sys/fs/cgroup/memory", "memory.limit_in_bytes")
            }
            _ => continue,
        };
        // This cgroup and every one above it.
        let mut dir = std::path::PathBuf::from(format!("{root}{path}"));
        loop {
            files.push(dir.join(file));
            if dir.as_os_str().len() <= root.len() || !dir.pop() {
                break;
            }
        }
    }
    files.push("/sys/fs/cgroup/memory.max".into());
    files.push("/sys/fs/cgroup/memory/memory.limit_in_bytes".into());
    files
        .iter()
        .filter_map(|p| std::fs::read_to_string(p).ok())
        .filter_map(|s| s.trim().parse::<u64>().ok())
        .min()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_bytes("1048576"), Ok(1 << 20));
        assert_eq!(parse_bytes("512M"), Ok(512 << 20));
        assert_eq!(parse_bytes("16GiB"), Ok(16 << 30));
        assert_eq!(parse_bytes("1.5g"), Ok(3 << 29));
        assert_eq!(parse_bytes(" 2 T "), Ok(2 << 40));
        for bad in ["", "G", "12Q", "-1G", "0", "1e400", "99999999999T"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_refusal_names_the_estimate_and_the_limit() {
        let b = Budget::new(1 << 30);
        assert!(b.check("x", 1 << 30).is_ok());
        let e = b.check("a 50000x50000 map", 5 << 30).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("5.0 GiB") && m.contains("1.0 GiB") && m.contains("--max-memory"),
            "{m}"
        );
        assert_eq!(e.exit_code(), 2);
        assert!(Budget::machine().limit() >= 1 << 20);
    }
}
