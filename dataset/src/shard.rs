//! Shards: a dataset's runs split among independent invocations (a scheduler's array tasks),
//! each run in exactly one shard, fixed by its index alone: run `i` is in shard `i mod N` of
//! `N`. A shard can be run anywhere, rerun after a kill, or run again into another folder;
//! it makes the same runs, byte for byte, since each run's seed comes from (K, i) alone.
//!
//! The shard of an invocation is given with `--shard I/N`, or read from the scheduler's
//! environment ([`from_env`]): a Slurm job array's `SLURM_ARRAY_TASK_ID` with
//! `SLURM_ARRAY_TASK_COUNT` or `SLURM_ARRAY_TASK_MIN`/`MAX` (and `STEP`), or a Kubernetes
//! Indexed Job's `JOB_COMPLETION_INDEX` with the Job's completions given as `--shards N`.

use crate::Error;
use std::fmt;

/// Shard `index` of `count`: the runs `i` with `i mod count == index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Shard {
    /// From 0 to `count - 1`.
    pub index: u64,
    /// The number of shards.
    pub count: u64,
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// `I/N` as given to `--shard`; the error says what is accepted.
    pub fn parse(text: &str) -> Result<Shard, Error> {
        let bad = || {
            Error::Request(format!(
                "--shard {text}: give the shard's index and the number of shards as I/N, two \
                 whole numbers with 0 <= I < N (e.g. --shard 0/4 for the first of four)"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let index = i.trim().parse().map_err(|_| bad())?;
        let count = n.trim().parse().map_err(|_| bad())?;
        Ok(Shard { index, count })
    }

    /// The shard of run `i` among `count` shards.
    pub fn of_run(i: u64, count: u64) -> Shard {
        Shard {
            index: i % count,
            count,
        }
    }

    /// Checks that this is a shard of a dataset of `runs` runs: at least one shard, the index
    /// below the count, and no more shards than runs (a shard without runs is a mistake in the
    /// launcher, not work). `from` says where the shard was read (`--shard 4/4`,
    /// `SLURM_ARRAY_TASK_ID=4 ...`).
    pub fn check(self, runs: u64, from: &str) -> Result<Shard, Error> {
        if self.count == 0 {
            return Err(Error::Request(format!(
                "{from}: a dataset is split into 1 or more shards, not 0"
            )));
        }
        if self.index >= self.count {
            return Err(Error::Request(format!(
                "{from}: shard index {} is out of range: the {} shards are numbered 0 to {}",
                self.index,
                self.count,
                self.count - 1
            )));
        }
        if self.count > runs {
            return Err(Error::Request(format!(
                "{from}: {} shards for {runs} runs would leave shards without a run; give at \
                 most {runs} shards (--count)",
                self.count
            )));
        }
        Ok(self)
    }

    /// Whether run `i` is in this shard.
    pub fn holds(self, i: u64) -> bool {
        i % self.count == self.index
    }

    /// The run indices of this shard in a dataset of `runs` runs, ascending.
    pub fn runs(self, runs: u64) -> impl Iterator<Item = u64> {
        (self.index..runs).step_by(self.count as usize)
    }

    /// The number of runs of this shard in a dataset of `runs` runs.
    pub fn len(self, runs: u64) -> u64 {
        runs.saturating_sub(self.index).div_ceil(self.count)
    }

    /// Whether this shard holds no run of a dataset of `runs` runs.
    pub fn is_empty(self, runs: u64) -> bool {
        self.len(runs) == 0
    }

    /// `I-of-N`: the shard's name in file names.
    pub fn tag(self) -> String {
        format!("{}-of-{}", self.index, self.count)
    }
}

/// The scheduler's variables read by [`from_env`].
pub const SLURM_VARS: [&str; 5] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_MAX",
    "SLURM_ARRAY_TASK_STEP",
];
/// The Kubernetes Indexed Job's index variable.
pub const K8S_INDEX: &str = "JOB_COMPLETION_INDEX";

/// The shard of an invocation from its scheduler's environment (`var` reads a variable), and
/// the words saying where it came from (`SLURM_ARRAY_TASK_ID=2 of 0..3 (SLURM_ARRAY_TASK_MIN,
/// SLURM_ARRAY_TASK_MAX)`). `shards` is `--shards N`: a Kubernetes Indexed Job does not tell
/// its completions to its pods, so they are given; with Slurm, which does, it must agree.
/// None when neither scheduler's variables are set (and no `--shards`): the whole dataset.
pub fn from_env(
    var: impl Fn(&str) -> Option<String>,
    shards: Option<u64>,
) -> Result<Option<(Shard, String)>, Error> {
    let number = |name: &str| -> Result<Option<u64>, Error> {
        match var(name) {
            None => Ok(None),
            Some(v) => v.trim().parse().map(Some).map_err(|_| {
                Error::Request(format!(
                    "{name}={v} in the environment is not a whole number ≥ 0: the scheduler \
                     sets it; give --shard I/N to choose the shard yourself"
                ))
            }),
        }
    };
    if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
        let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
        let (min, max) = (
            number("SLURM_ARRAY_TASK_MIN")?,
            number("SLURM_ARRAY_TASK_MAX")?,
        );
        let min_id = min.unwrap_or(0);
        let (count, said) = match (number("SLURM_ARRAY_TASK_COUNT")?, min, max) {
            (Some(c), _, _) => (c, format!("SLURM_ARRAY_TASK_COUNT={c}")),
            (None, Some(lo), Some(hi)) if hi >= lo => (
                (hi - lo) / step + 1,
                format!("SLURM_ARRAY_TASK_MIN={lo}, SLURM_ARRAY_TASK_MAX={hi}"),
            ),
            _ => {
                return Err(Error::Request(format!(
                    "SLURM_ARRAY_TASK_ID={id} is set but neither SLURM_ARRAY_TASK_COUNT nor \
                     SLURM_ARRAY_TASK_MIN and SLURM_ARRAY_TASK_MAX are: the number of shards \
                     is unknown; give --shard I/N"
                )));
            }
        };
        if id < min_id || (id - min_id) % step != 0 {
            return Err(Error::Request(format!(
                "SLURM_ARRAY_TASK_ID={id} is not a task of an array from {min_id} in steps of \
                 {step}: give --shard I/N"
            )));
        }
        let shard = Shard {
            index: (id - min_id) / step,
            count,
        };
        if let Some(n) = shards.filter(|&n| n != count) {
            return Err(Error::Request(format!(
                "--shards {n} disagrees with the Slurm array of {count} tasks ({said}); leave \
                 --shards out under Slurm, or give --shard I/N"
            )));
        }
        let offset = if min_id > 0 || step > 1 {
            format!(", SLURM_ARRAY_TASK_MIN={min_id}, step {step}")
        } else {
            String::new()
        };
        return Ok(Some((
            shard,
            format!("SLURM_ARRAY_TASK_ID={id}{offset}, {said}"),
        )));
    }
    if let Some(index) = number(K8S_INDEX)? {
        let Some(count) = shards else {
            return Err(Error::Request(format!(
                "{K8S_INDEX}={index} is set (a Kubernetes Indexed Job) but not the number of \
                 shards: give --shards N, the Job's completions"
            )));
        };
        return Ok(Some((
            Shard { index, count },
            format!("{K8S_INDEX}={index}, --shards {count}"),
        )));
    }
    match shards {
        Some(n) => Err(Error::Request(format!(
            "--shards {n} without {K8S_INDEX} in the environment (set by a Kubernetes Indexed \
             Job): give --shard I/{n} to run a shard by hand"
        ))),
        None => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::HashMap;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| map.get(k).cloned()
    }

    proptest! {
        /// Every run is in exactly one shard, and `runs`/`len` list the runs `holds` says are
        /// in it (checked against a plain filter of 0..runs).
        #[test]
        fn shards_partition_the_runs(runs in 1u64..400, count in 1u64..50) {
            prop_assume!(count <= runs);
            let mut seen = vec![0u32; runs as usize];
            for index in 0..count {
                let s = Shard { index, count };
                let listed: Vec<u64> = s.runs(runs).collect();
                let filtered: Vec<u64> = (0..runs).filter(|&i| s.holds(i)).collect();
                prop_assert_eq!(&listed, &filtered);
                prop_assert_eq!(s.len(runs), listed.len() as u64);
                for i in listed {
                    seen[i as usize] += 1;
                    prop_assert_eq!(Shard::of_run(i, count), s);
                }
            }
            prop_assert!(seen.iter().all(|&n| n == 1));
        }
    }

    #[test]
    fn a_shard_is_parsed_and_checked() {
        let s = Shard::parse("2/4").unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        assert_eq!(s.to_string(), "2/4");
        assert_eq!(s.tag(), "2-of-4");
        assert!(s.check(20, "--shard 2/4").is_ok());
        for bad in ["2", "a/4", "2/", "-1/4", "2/4/1"] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains(&format!("--shard {bad}")), "{e}");
        }
        let e = Shard::parse("4/4")
            .unwrap()
            .check(20, "--shard 4/4")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "--shard 4/4: shard index 4 is out of range: the 4 shards are numbered 0 to 3"
        );
        let e = Shard { index: 0, count: 0 }.check(20, "--shard 0/0");
        assert!(e.unwrap_err().to_string().contains("not 0"));
        let e = Shard {
            index: 0,
            count: 30,
        }
        .check(20, "--shard 0/30");
        assert!(e.unwrap_err().to_string().contains("at most 20 shards"));
    }

    #[test]
    fn slurm_arrays_give_the_shard_by_count_or_by_bounds() {
        let (s, said) = from_env(
            env(&[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ]),
            None,
        )
        .unwrap()
        .unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        assert_eq!(said, "SLURM_ARRAY_TASK_ID=2, SLURM_ARRAY_TASK_COUNT=4");
        // --array=1-7:2 is the tasks 1, 3, 5, 7: task 5 is the third shard of four.
        let (s, said) = from_env(
            env(&[
                ("SLURM_ARRAY_TASK_ID", "5"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "7"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
            ]),
            None,
        )
        .unwrap()
        .unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        assert!(said.contains("SLURM_ARRAY_TASK_MAX=7"), "{said}");
        let e = from_env(env(&[("SLURM_ARRAY_TASK_ID", "2")]), None).unwrap_err();
        assert!(e.to_string().contains("number of shards is unknown"), "{e}");
        let e = from_env(env(&[("SLURM_ARRAY_TASK_ID", "x")]), None).unwrap_err();
        assert!(e.to_string().starts_with("SLURM_ARRAY_TASK_ID=x"), "{e}");
        let e = from_env(
            env(&[
                ("SLURM_ARRAY_TASK_ID", "1"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ]),
            Some(8),
        )
        .unwrap_err();
        assert!(e.to_string().contains("--shards 8 disagrees"), "{e}");
    }

    #[test]
    fn kubernetes_gives_the_index_and_shards_the_count() {
        let (s, said) = from_env(env(&[(K8S_INDEX, "7")]), Some(10))
            .unwrap()
            .unwrap();
        assert_eq!(
            s,
            Shard {
                index: 7,
                count: 10
            }
        );
        assert_eq!(said, "JOB_COMPLETION_INDEX=7, --shards 10");
        let e = from_env(env(&[(K8S_INDEX, "7")]), None).unwrap_err();
        assert!(e.to_string().contains("give --shards N"), "{e}");
        let e = from_env(env(&[]), Some(10)).unwrap_err();
        assert!(e.to_string().contains("--shard I/10"), "{e}");
        assert_eq!(from_env(env(&[]), None).unwrap(), None);
    }
}
