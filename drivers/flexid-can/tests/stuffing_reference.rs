//! A naive reference for `timing::frame_bits`: a bit-level CAN encoder (SOF to CRC, CRC-15
//! computed bit by bit) and the stuffing rule applied literally (after five equal bits a
//! complementary bit is inserted, and counts towards the next run).

use flexid_can::timing::{frame_bits, IFS_BITS};

/// Stuff bits the rule inserts into `bits` (SOF to the end of the CRC).
fn stuff_bits(bits: &[bool]) -> u32 {
    let mut inserted = 0;
    let mut run = 0;
    let mut last = None;
    for &b in bits {
        if Some(b) == last {
            run += 1;
        } else {
            last = Some(b);
            run = 1;
        }
        if run == 5 {
            inserted += 1;
            last = Some(!b); // the stuff bit starts the next run
            run = 1;
        }
    }
    inserted
}

fn push(bits: &mut Vec<bool>, value: u32, n: u32) {
    for i in (0..n).rev() {
        bits.push(value >> i & 1 == 1);
    }
}

/// SOF .. CRC of a standard data frame (dominant = false).
fn standard_frame_bits(id: u16, data: &[u8]) -> Vec<bool> {
    let mut bits = vec![false]; // SOF
    push(&mut bits, id as u32, 11);
    bits.push(false); // RTR: data frame
    bits.push(false); // IDE: standard
    bits.push(false); // r0
    push(&mut bits, data.len() as u32, 4);
    for &b in data {
        push(&mut bits, b as u32, 8);
    }
    let mut crc: u16 = 0;
    for &b in &bits {
        let next = b ^ (crc >> 14 & 1 == 1);
        crc = (crc << 1) & 0x7fff;
        if next {
            crc ^= 0x4599;
        }
    }
    push(&mut bits, crc as u32, 15);
    bits
}

/// Total bits on the wire: stuffed SOF..CRC, CRC delimiter, ACK slot and delimiter, EOF, IFS.
fn wire_bits(id: u16, data: &[u8]) -> u32 {
    let b = standard_frame_bits(id, data);
    b.len() as u32 + stuff_bits(&b) + 1 + 1 + 1 + 7 + IFS_BITS
}

#[test]
fn stuffing_bound_is_the_worst_case_of_the_rule() {
    // every bit string of length L: the most stuff bits the rule inserts is
    // floor((L - 1) / 4), the term frame_bits uses
    for len in 1..=20usize {
        let mut worst = 0;
        let mut bits = vec![false; len];
        for v in 0u32..(1 << len) {
            for (i, b) in bits.iter_mut().enumerate() {
                *b = v >> i & 1 == 1;
            }
            worst = worst.max(stuff_bits(&bits));
        }
        assert_eq!(worst, (len as u32 - 1) / 4, "L = {len}");
    }
    // and the pattern that reaches it at a frame's length (8 data bytes: g + 8n = 98)
    let mut bits = vec![false; 5];
    while bits.len() < 98 {
        let v = !bits[bits.len() - 1];
        bits.extend([v; 4]);
    }
    bits.truncate(98);
    assert_eq!(stuff_bits(&bits), 97 / 4);
    assert_eq!(98 + 97 / 4 + 10 + IFS_BITS, frame_bits(8, false));
}

#[test]
fn real_frames_never_exceed_frame_bits() {
    // CANopen frames of the default mapping and pseudo-random ones (xorshift)
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut tightest = u32::MAX;
    for k in 0..20_000 {
        let n = (k % 9) as usize;
        let id = (next() & 0x7ff) as u16;
        let mut data = [0u8; 8];
        for d in data.iter_mut() {
            *d = if k % 3 == 0 { 0 } else { next() as u8 };
        }
        let got = wire_bits(id, &data[..n]);
        let bound = frame_bits(n as u8, false);
        assert!(got <= bound, "id {id:#x} {:?}: {got} > {bound}", &data[..n]);
        assert!(got >= 44 + 8 * n as u32 + IFS_BITS);
        tightest = tightest.min(bound - got);
    }
    // SYNC (0x080, no data): unstuffed 47 + stuffing; well below the 55-bit bound
    let sync = wire_bits(0x080, &[]);
    assert!(sync < frame_bits(0, false), "{sync}");
    assert!(tightest < 20, "bound never approached: {tightest}");
}
