//! vmt-chatter: milling stability and chatter detection. It reads the tool's modal parameters
//! and cutting coefficients (vmt-model's `cutting`) and measured or simulated signals; it never
//! calls the simulator.
pub mod detect;
pub mod filter;
pub mod stability;
