//! The simulated test as a CSV file: the sample times and both channels (`t,u,y`, the
//! reference as `u` and the probe as `y`), readable as a step test.

use std::io::Write;

use super::SimulatedTest;

impl SimulatedTest {
    /// Writes the test as CSV to `out`: the header `t,u,y`, then one row a sample, the time
    /// in s to the nanosecond and the channels in Pa as they are (the shortest text that reads
    /// back to the same number).
    ///
    /// # Errors
    /// `out`'s.
    pub fn write_csv(&self, out: &mut dyn Write) -> std::io::Result<()> {
        out.write_all(b"t,u,y\n")?;
        for ((t, u), y) in self.t.iter().zip(&self.reference).zip(&self.probe) {
            writeln!(out, "{t:.9},{u},{y}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::ImpulseResponse;
    use super::*;

    #[test]
    fn the_csv_has_its_header_then_a_row_a_sample() {
        // Values whose text is known: the time to the nanosecond, the channels as they are.
        let test = SimulatedTest {
            t: vec![0.0, 1e-4, 2.5e-4],
            reference: vec![0.0, 100.0, 99.5],
            probe: vec![-1.5e-7, 0.25, 1e21],
            excitation: Vec::new(),
            probe_clean: Vec::new(),
            impulse: ImpulseResponse {
                rate_hz: 320_000.0,
                taps: vec![1.0],
                fft_length: 2,
                tail_energy: 0.0,
                noncausal_energy: 0.0,
                taper_start_hz: 128_000.0,
            },
            adc: None,
        };
        let mut out = Vec::new();
        test.write_csv(&mut out).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "t,u,y\n0.000000000,0,-0.00000015\n0.000100000,100,0.25\n\
             0.000250000,99.5,1000000000000000000000\n"
        );
    }
}
