//! Reading the files the analysis commands are given: an MCAP run is streamed from disk (the
//! mcap crate's `io::MessageReader`, memory of about one chunk, whatever the run's length: a
//! 277 MB Kwon run had been read whole into memory), any other file (a CSV) is read whole.

use crate::error::FileError;
use mcap::sans_io::LinearReaderOptions;
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// A file as the analysis commands take it.
pub enum Input {
    /// An MCAP file (by its magic bytes), to be read with [`messages`].
    Mcap,
    /// Any other file, whole.
    Other(Vec<u8>),
}

/// Whether `path` is an MCAP file, or its bytes if it is not; errors name `file`.
pub fn open(path: &Path, file: &str) -> Result<Input, FileError> {
    let err = |e: std::io::Error| FileError::input(file, None, e.to_string());
    let mut f = File::open(path).map_err(err)?;
    let mut head = Vec::with_capacity(mcap::MAGIC.len());
    f.by_ref()
        .take(mcap::MAGIC.len() as u64)
        .read_to_end(&mut head)
        .map_err(err)?;
    if head == mcap::MAGIC {
        return Ok(Input::Mcap);
    }
    f.read_to_end(&mut head).map_err(err)?;
    Ok(Input::Other(head))
}

/// The longest record read, bytes (a chunk compressed or not; ours are about 1 MB): a longer
/// one is damage. The readers allocate a record's stated length before reading it, and a
/// corrupt length field (4.4 TB in a review) aborted the process instead of giving an error.
const RECORD_LENGTH_LIMIT: usize = 1 << 30;

/// The messages of the MCAP file `path`, streamed in file order and linked to their channels;
/// a damaged record is an error naming `file`, with its causes.
pub fn messages(
    path: &Path,
    file: &str,
) -> Result<impl Iterator<Item = Result<mcap::Message<'static>, FileError>>, FileError> {
    let f = File::open(path).map_err(|e| FileError::input(file, None, e.to_string()))?;
    let file = file.to_string();
    Ok(mcap::io::MessageReader::new_with_options(
        BufReader::new(f),
        LinearReaderOptions::default().with_record_length_limit(RECORD_LENGTH_LIMIT),
    )
    .map(move |m| {
        m.map_err(|e| {
            let why = crate::error::with_causes(&e);
            FileError::input(&file, None, format!("a damaged MCAP record: {why}"))
        })
    }))
}

/// The summary section of the MCAP file `path`, if it has one (read with a few seeks, not
/// through the file); `None` also when it cannot be read.
pub fn summary(path: &Path) -> Option<mcap::Summary> {
    let mut f = File::open(path).ok()?;
    let size = f.metadata().ok()?.len();
    let mut reader = SummaryReader::new_with_options(
        SummaryReaderOptions::default()
            .with_file_size(size)
            .with_record_length_limit(RECORD_LENGTH_LIMIT),
    );
    while let Some(event) = reader.next_event() {
        match event.ok()? {
            SummaryReadEvent::ReadRequest(need) => {
                let n = f.read(reader.insert(need)).ok()?;
                reader.notify_read(n);
            }
            SummaryReadEvent::SeekRequest(to) => reader.notify_seeked(f.seek(to).ok()?),
        }
    }
    reader.finish()
}
