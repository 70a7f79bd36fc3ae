//! Milling stability and chatter detection.
