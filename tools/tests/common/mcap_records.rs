//! The records of an MCAP file read byte by byte (opcode u8, length u64 little-endian,
//! content), for tests that check where a record is or damage one.

/// One record: its offset in the file, its opcode and, for a metadata record, its name.
// Each test binary that includes this file reads the fields it needs.
#[allow(dead_code)]
pub struct Record {
    pub at: usize,
    pub opcode: u8,
    pub name: String,
}

/// The records of the MCAP bytes `b` in file order, from after the magic up to the data end.
pub fn records(b: &[u8]) -> Vec<Record> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= b.len() {
        let opcode = b[at];
        let len = u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        let name = if opcode == 0x0C {
            let n = u32::from_le_bytes(b[at + 9..at + 13].try_into().unwrap()) as usize;
            String::from_utf8_lossy(&b[at + 13..at + 13 + n]).into_owned()
        } else {
            String::new()
        };
        out.push(Record { at, opcode, name });
        if opcode == 0x0F {
            break; // data end
        }
        at += 9 + len;
    }
    out
}
