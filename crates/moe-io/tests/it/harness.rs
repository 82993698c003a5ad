//! The fuzz harness shared by the format crates' tests (`moe-io`'s readers, `moe-record`'s
//! episode reader, which includes this file): every prefix of a valid sample, byte-flipped and
//! spliced copies, random bytes and keyword soup, each run with panics caught. A reader must
//! return a typed error or a value that passes its check.

use std::panic::{AssertUnwindSafe, catch_unwind};

use moe_io::IoError;

/// The workspace's seeded generator, with a `usize` range helper for the fuzz loops.
pub(crate) struct Fuzz(pub(crate) moe_geom::SeededRng);

impl Fuzz {
    pub(crate) fn new(seed: u64) -> Self {
        Self(moe_geom::SeededRng::new(seed))
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n` (n > 0).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        self.0.below(n as u64) as usize
    }
}

/// What one reader made of one input.
pub(crate) enum Outcome {
    /// A value that passed its validity check.
    Valid,
    /// A typed error.
    Error,
    /// A value that violates the reader's guarantees, or a caught parser panic.
    Bad(String),
}

pub(crate) type Reader = fn(&[u8]) -> Outcome;

pub(crate) fn from_result<T>(
    r: Result<T, IoError>,
    check: impl FnOnce(&T) -> Option<String>,
) -> Outcome {
    match r {
        Ok(v) => match check(&v) {
            None => Outcome::Valid,
            Some(why) => Outcome::Bad(why),
        },
        Err(IoError::ParserPanic { parser, .. }) => Outcome::Bad(format!("{parser} panicked")),
        Err(_) => Outcome::Error,
    }
}

/// Keyword soup for each format family, so random inputs reach past the first token.
const TOKENS: &[&str] = &[
    "v",
    "f",
    "vt",
    "vn",
    "o",
    "g",
    "l",
    "p",
    "#",
    "1",
    "-1",
    "0",
    "2",
    "3",
    "4294967295",
    "-9223372036854775808",
    "1e308",
    "nan",
    "inf",
    "0.5",
    "/",
    "//",
    "1/2/3",
    "ply",
    "format",
    "ascii",
    "binary_little_endian",
    "binary_big_endian",
    "1.0",
    "element",
    "vertex",
    "face",
    "property",
    "float",
    "double",
    "uchar",
    "int",
    "uint",
    "list",
    "vertex_indices",
    "x",
    "y",
    "z",
    "red",
    "end_header",
    "solid",
    "facet",
    "normal",
    "outer",
    "loop",
    "endloop",
    "endfacet",
    "endsolid",
    "preset",
    "=",
    "\"two-finger\"",
    "[finger]",
    "[[fingers]]",
    "mesh",
    "params",
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    "\"",
    "length_m",
    "vertex_budget",
    "marker_vertices",
    "\n",
    " ",
];

/// Runs one reader on one input, catching panics.
pub(crate) fn run_case(
    name: &str,
    reader: Reader,
    input: &[u8],
    kind: &str,
    failures: &mut Vec<String>,
) -> bool {
    match catch_unwind(AssertUnwindSafe(|| reader(input))) {
        Ok(Outcome::Valid) => true,
        Ok(Outcome::Error) => false,
        Ok(Outcome::Bad(why)) => {
            failures.push(format!("{name} {kind} ({} bytes): {why}", input.len()));
            false
        }
        Err(_) => {
            failures.push(format!("{name} {kind} ({} bytes): panicked", input.len()));
            false
        }
    }
}

/// Runs every reader on every mutation of its sample; panics with the list of failures.
///
/// Each unmodified sample must be accepted. Returns how many cases ran.
pub(crate) fn fuzz_readers(seed: u64, samples: Vec<(&'static str, Reader, Vec<u8>)>) -> usize {
    let mut rng = Fuzz::new(seed);
    let mut failures = Vec::new();
    let mut cases = 0usize;
    let mut valid = 0usize;
    for (name, reader, sample) in samples {
        // The untouched sample is valid.
        assert!(
            matches!(reader(&sample), Outcome::Valid),
            "{name}: the unmodified sample must be accepted"
        );
        // Every prefix.
        for len in 0..sample.len() {
            cases += 1;
            valid += usize::from(run_case(
                name,
                reader,
                &sample[..len],
                "prefix",
                &mut failures,
            ));
        }
        // Byte flips: 1–4 random bytes replaced by random values or single-bit flips.
        for _ in 0..1000 {
            let mut s = sample.clone();
            for _ in 0..1 + rng.below(4) {
                let i = rng.below(s.len());
                s[i] = if rng.below(2) == 0 {
                    rng.next_u64() as u8
                } else {
                    s[i] ^ (1 << rng.below(8))
                };
            }
            cases += 1;
            valid += usize::from(run_case(name, reader, &s, "byte flip", &mut failures));
        }
        // Spliced: a random slice of the sample repeated or dropped.
        for _ in 0..100 {
            let a = rng.below(sample.len());
            let b = a + rng.below(sample.len() - a);
            let mut s = sample[..b].to_vec();
            s.extend_from_slice(&sample[a..]);
            cases += 1;
            valid += usize::from(run_case(name, reader, &s, "splice", &mut failures));
        }
        // Random bytes and keyword soup.
        for _ in 0..150 {
            let n = rng.below(300);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
            cases += 1;
            valid += usize::from(run_case(
                name,
                reader,
                &bytes,
                "random bytes",
                &mut failures,
            ));
            let mut soup = String::new();
            for _ in 0..rng.below(120) {
                soup.push_str(TOKENS[rng.below(TOKENS.len())]);
                soup.push(if rng.below(4) == 0 { '\n' } else { ' ' });
            }
            cases += 1;
            valid += usize::from(run_case(
                name,
                reader,
                soup.as_bytes(),
                "token soup",
                &mut failures,
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // Some mutated inputs still parse (e.g. a flipped digit): the checks above saw them too.
    assert!(
        valid > 0,
        "no mutated input was accepted; the fuzzing never reached a value check"
    );
    println!("fuzz: {cases} cases, {valid} accepted as valid, 0 panics");
    cases
}
