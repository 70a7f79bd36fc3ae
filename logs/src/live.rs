//! `run.mcap` and `run.rrd` written while the job runs: the simulator hands its records to
//! [`RunFiles`] block by block (a [`LogSink`]), and two threads write them, one per file, while
//! the simulation goes on. A long job's log is never in memory whole, and on two cores the
//! files take little time beyond the simulation's.
//!
//! The MCAP file is byte for byte the one [`write_mcap`](super::write_mcap) makes of the
//! finished run; the recording has the same entities and contents as
//! [`write_rrd`](super::write_rrd)'s. The two files are renamed to their names together, once
//! both are complete: a run has both or neither.

use super::mcap::McapFile;
use super::rerun::RrdFile;
use super::{Partial, RunFile};
use crate::error::FileError;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use vmt_sim::run::{BallbarTrace, LogBlock, LogSink, Run, Stream};

/// Blocks waiting for each writer (about 2 MB each): what a slow disk can hold up.
const QUEUE: usize = 4;

/// What the writer threads are sent (each the same, shared).
#[derive(Clone)]
enum Message {
    /// The streams' rows and traces' samples of a block (every trace, most with no sample).
    Block(Arc<(Vec<Stream>, Vec<BallbarTrace>)>),
    /// The finished run.
    Finish(Arc<Run>),
}

/// The complete file under its partial name, or none if the run ended without finishing.
type Outcome = Result<Option<Partial>, FileError>;

/// One file's thread and the way to it.
struct Writer {
    path: PathBuf,
    queue: SyncSender<Message>,
    thread: JoinHandle<Outcome>,
}

impl Writer {
    fn spawn<F: RunFile + 'static>(path: PathBuf, opening: Run) -> Self {
        let (queue, blocks) = sync_channel(QUEUE);
        let target = path.clone();
        let thread = std::thread::spawn(move || write::<F>(&target, &opening, blocks));
        Self {
            path,
            queue,
            thread,
        }
    }

    /// Waits for the thread and returns what it made.
    fn join(self) -> Outcome {
        drop(self.queue);
        self.thread
            .join()
            .unwrap_or_else(|_| Err(FileError::output_message(&self.path, "its writer failed")))
    }
}

/// The body of a writer thread: creates the file, writes the blocks as they come and completes
/// it with the run. A run that ends without [`Message::Finish`] (the simulation failed) drops
/// the file, which removes it.
fn write<F: RunFile>(path: &Path, opening: &Run, blocks: Receiver<Message>) -> Outcome {
    let mut file = F::create(path, opening)?;
    for m in blocks {
        match m {
            Message::Block(b) => file.block(&b.0, &b.1)?,
            Message::Finish(run) => return file.complete(&run).map(Some),
        }
    }
    Ok(None)
}

/// `run.mcap` and `run.rrd` in a folder, written while the job runs.
pub struct RunFiles {
    dir: PathBuf,
    writers: Vec<Writer>,
}

impl RunFiles {
    /// The files of a run to be written into `dir` (which must exist).
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
            writers: Vec::new(),
        }
    }

    fn send(&self, m: Message) -> Result<(), String> {
        for w in &self.writers {
            // A writer that has stopped has an error, which `finish` or `abandon` reports.
            w.queue
                .send(m.clone())
                .map_err(|_| format!("writing {} failed", w.path.display()))?;
        }
        Ok(())
    }

    /// Completes the files with the finished `run` (whose `servo` rows went to the files as it
    /// ran), renames them to their names once both are complete, and returns the run and the
    /// files' paths.
    pub fn finish(mut self, run: Run) -> Result<(Run, Vec<PathBuf>), FileError> {
        let run = Arc::new(run);
        let sent = self.send(Message::Finish(Arc::clone(&run)));
        let made = self.join_all()?;
        sent.map_err(|e| FileError::output_message(&self.dir, e))?;
        let mut files = Vec::new();
        for p in made.into_iter().flatten() {
            let path = p.target().to_path_buf();
            if let Err(e) = p.commit() {
                // Both or neither: the files renamed already go too.
                files.iter().for_each(|f| drop(std::fs::remove_file(f)));
                return Err(e);
            }
            files.push(path);
        }
        // The writers have let go of the run.
        let run = Arc::try_unwrap(run).unwrap_or_else(|shared| (*shared).clone());
        Ok((run, files))
    }

    /// Ends the files of a run that failed, removing them; a writer's error if one had failed
    /// (which would explain the run's).
    pub fn abandon(mut self) -> Result<(), FileError> {
        self.join_all().map(drop)
    }

    /// Waits for every writer: what each made, or the first error.
    fn join_all(&mut self) -> Result<Vec<Option<Partial>>, FileError> {
        let outcomes: Vec<Outcome> = self.writers.drain(..).map(Writer::join).collect();
        outcomes.into_iter().collect()
    }
}

impl Drop for RunFiles {
    /// Joins the writers of files neither finished nor abandoned (the caller unwound), so that
    /// they remove their partial files before the process ends.
    fn drop(&mut self) {
        let _ = self.join_all();
    }
}

impl LogSink for RunFiles {
    fn start(&mut self, run: &Run) -> Result<(), String> {
        self.writers = vec![
            Writer::spawn::<McapFile>(self.dir.join("run.mcap"), run.clone()),
            Writer::spawn::<RrdFile>(self.dir.join("run.rrd"), run.clone()),
        ];
        Ok(())
    }

    fn block(&mut self, block: &LogBlock<'_>) -> Result<(), String> {
        let traces: Vec<BallbarTrace> = block
            .ballbar
            .iter()
            .zip(block.new_samples)
            .map(|(t, r)| t.samples(r.clone()))
            .collect();
        self.send(Message::Block(Arc::new((block.streams.to_vec(), traces))))
    }
}
