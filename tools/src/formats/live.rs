//! `run.mcap` and `run.rrd` written while the job runs: the simulator hands its records to
//! [`RunFiles`] block by block (a [`LogSink`]), and two threads write them, one per file, while
//! the simulation goes on. A long job's log is never in memory whole, and on two cores the
//! files take little time beyond the simulation's.
//!
//! The MCAP file is byte for byte the one [`write_mcap`](super::write_mcap) makes of the
//! finished run; the recording has the same entities and contents as
//! [`write_rrd`](super::write_rrd)'s.

use super::mcap::McapFile;
use super::rerun::RrdFile;
use crate::error::CliError;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use vmt_sim::run::{BallbarTrace, LogBlock, LogSink, Run, Stream};

/// Blocks waiting for each writer: the memory a slow disk can hold up (about 2 MB a block).
const QUEUE: usize = 4;

/// What the writer threads are sent.
enum Message {
    /// The streams' rows and traces' samples of a block (every trace, most with no sample).
    Block(Vec<Stream>, Vec<BallbarTrace>),
    /// The finished run.
    Finish(Box<Run>),
}

/// A file of a run written block by block.
trait BlockFile: Sized {
    fn create(path: &Path, opening: &Run) -> Result<Self, CliError>;
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), CliError>;
    fn finish(self, run: &Run) -> Result<(), CliError>;
}

impl BlockFile for McapFile {
    fn create(path: &Path, opening: &Run) -> Result<Self, CliError> {
        McapFile::create(path, opening)
    }
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), CliError> {
        McapFile::block(self, streams, traces)
    }
    fn finish(self, run: &Run) -> Result<(), CliError> {
        McapFile::finish(self, run)
    }
}

impl BlockFile for RrdFile {
    fn create(path: &Path, opening: &Run) -> Result<Self, CliError> {
        RrdFile::create(path, opening)
    }
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), CliError> {
        RrdFile::block(self, streams, traces)
    }
    fn finish(self, run: &Run) -> Result<(), CliError> {
        RrdFile::finish(self, run)
    }
}

/// One file's thread and the way to it.
struct Writer {
    path: PathBuf,
    queue: SyncSender<Arc<Message>>,
    /// `Ok(true)` once the file is complete, `Ok(false)` if the run ended without finishing.
    thread: JoinHandle<Result<bool, CliError>>,
}

impl Writer {
    fn spawn<F: BlockFile + 'static>(path: PathBuf, opening: Run) -> Self {
        let (queue, blocks) = sync_channel(QUEUE);
        let target = path.clone();
        let thread = std::thread::spawn(move || write::<F>(&target, &opening, blocks));
        Self {
            path,
            queue,
            thread,
        }
    }

    /// Waits for the thread: whether the file is complete, or its error.
    fn join(self) -> Result<bool, CliError> {
        drop(self.queue);
        self.thread
            .join()
            .unwrap_or_else(|_| Err(CliError::output(&self.path, "its writer failed")))
    }
}

/// The body of a writer thread: creates the file, writes the blocks as they come and finishes
/// it with the run. A run that ends without [`Message::Finish`] (the simulation failed) drops
/// the file, which removes it.
fn write<F: BlockFile>(
    path: &Path,
    opening: &Run,
    blocks: Receiver<Arc<Message>>,
) -> Result<bool, CliError> {
    let mut file = F::create(path, opening)?;
    for m in blocks {
        match &*m {
            Message::Block(streams, traces) => file.block(streams, traces)?,
            Message::Finish(run) => return file.finish(run).map(|()| true),
        }
    }
    Ok(false)
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
        let m = Arc::new(m);
        for w in &self.writers {
            // A writer that has stopped has an error, which `finish` reports.
            w.queue
                .send(Arc::clone(&m))
                .map_err(|_| format!("writing {} failed", w.path.display()))?;
        }
        Ok(())
    }

    /// Completes the files with the finished `run` (whose `servo` rows went to the files as it
    /// ran) and returns their paths; or, with no run (the simulation failed), removes them and
    /// returns the first writer's error if one failed.
    pub fn finish(self, run: Option<&Run>) -> Result<Vec<PathBuf>, CliError> {
        let sent = match run {
            Some(r) => self.send(Message::Finish(Box::new(r.clone()))),
            None => Ok(()),
        };
        let mut files = Vec::new();
        let mut first_error = None;
        for w in self.writers {
            let path = w.path.clone();
            match w.join() {
                Ok(true) => files.push(path),
                Ok(false) => {}
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        match (first_error, sent) {
            (Some(e), _) => Err(e),
            (None, Err(e)) => Err(CliError::output(&self.dir, e)),
            (None, Ok(())) => Ok(files),
        }
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
        let traces = block
            .ballbar
            .iter()
            .zip(block.new_samples)
            .map(|(t, r)| BallbarTrace {
                label: t.label.clone(),
                plane: t.plane.clone(),
                direction: t.direction.clone(),
                radius_mm: t.radius_mm,
                feed_mm_min: t.feed_mm_min,
                times_s: t.times_s[r.clone()].to_vec(),
                angle_deg: t.angle_deg[r.clone()].to_vec(),
                deviation_um: t.deviation_um[r.clone()].to_vec(),
            })
            .collect();
        self.send(Message::Block(block.streams.to_vec(), traces))
    }
}
