//! The OGM detector's GPU passes over one tile: classify, count, and the ordered write of the keypoints.

use super::*;

impl GpuBackend {
    /// Runs one tile, whose pixels are already queued in pixel buffer `slot`; appends its keypoints (map
    /// coordinates) in (y, x) order. While the GPU classifies it, the `next` tile uploads into the other
    /// buffer.
    pub(super) fn run_tile(
        &mut self,
        image: &MapImage,
        t: &tiles::Tile,
        slot: usize,
        next: Option<&tiles::Tile>,
        unknown_as_occupied: bool,
        out: &mut Vec<Keypoint>,
    ) -> Result<()> {
        let words = t.stride() * t.buf_h();
        let (gx, gy) = self.dispatch_shape(words);
        if gy > self.max_groups {
            return Err(Error::Internal(format!(
                "tile of {} words needs {gx}x{gy} workgroups, over the device's {}",
                words, self.max_groups
            )));
        }
        let groups = u64::from(gx) * u64::from(gy);
        let mut params = Params {
            buf_w: t.buf_w(),
            buf_h: t.buf_h(),
            stride: t.stride(),
            words,
            core_x0: t.core[0] - t.buf[0],
            core_y0: t.core[1] - t.buf[1],
            core_x1: t.core[2] - t.buf[0],
            core_y1: t.core[3] - t.buf[1],
            origin_x: t.buf[0],
            origin_y: t.buf[1],
            unknown_as_occupied: u32::from(unknown_as_occupied),
            groups_x: gx,
            ..Params::default()
        };
        let bytes = t.bytes();
        let pixels = self.pixels[slot]
            .get(&self.device, bytes, self.max_binding)
            .clone();
        let states = self
            .states
            .get(&self.device, bytes, self.max_binding)
            .clone();
        let counts = self
            .counts
            .get(&self.device, groups * 4, self.max_binding)
            .clone();
        self.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));

        // Pass 1: classify and count.
        let bg_classify = self.bind(
            &self.classify,
            &[
                (0, &self.params),
                (1, &self.class_table),
                (2, &pixels),
                (3, &states),
            ],
        );
        let bg_count = self.bind(
            &self.count,
            &[
                (0, &self.params),
                (1, &self.rule_table),
                (2, &states),
                (3, &counts),
            ],
        );
        let encoder = self.encode(&[
            (&self.classify, &bg_classify, (gx, gy)),
            (&self.count, &bg_count, (gx, gy)),
        ]);
        let raw = self.submit_and_read(encoder, &counts, groups * 4, true, |me| {
            if let Some(n) = next {
                me.upload(image, n, 1 - slot);
            }
        })?;
        // The groups that found keypoints, each with its first position in the list (an exclusive
        // prefix sum of the counts). Only these are dispatched in the write pass.
        let mut active: Vec<[u32; 2]> = Vec::new();
        let mut total = 0u64;
        for (g, c) in raw.chunks_exact(4).take(groups as usize).enumerate() {
            let n = u32::from_le_bytes(c.try_into().expect("4 bytes"));
            if n > 0 {
                active.push([g as u32, total as u32]);
                total += u64::from(n);
            }
        }
        if total == 0 {
            return Ok(());
        }
        let active_buf = self
            .offsets
            .get(&self.device, active.len() as u64 * 8, self.max_binding)
            .clone();
        self.queue
            .write_buffer(&active_buf, 0, bytemuck::cast_slice(&active));
        let (ax, ay) = self.dispatch_shape_groups(active.len() as u32);
        params.groups_x = ax;
        params.active_len = active.len() as u32;

        // Pass 2: write, in chunks of what one binding (or the test cap) holds.
        let per_pass = (self.max_binding / KEYPOINT_BYTES)
            .min(
                self.options
                    .max_keypoints_per_pass
                    .map_or(u64::MAX, u64::from),
            )
            .max(1);
        let mut start = 0u64;
        while start < total {
            let len = per_pass.min(total - start);
            let want = len.max(u64::from(self.options.initial_keypoint_capacity));
            let kp = self
                .keypoints
                .get(
                    &self.device,
                    want * KEYPOINT_BYTES,
                    per_pass * KEYPOINT_BYTES,
                )
                .clone();
            self.stats.keypoint_capacity = self.keypoints.size / KEYPOINT_BYTES;
            params.out_start = start as u32;
            params.out_end = (start + len) as u32;
            self.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            let bg_write = self.bind(
                &self.write,
                &[
                    (0, &self.params),
                    (1, &self.rule_table),
                    (2, &states),
                    (4, &active_buf),
                    (5, &kp),
                ],
            );
            let encoder = self.encode(&[(&self.write, &bg_write, (ax, ay))]);
            let raw = self.submit_and_read(encoder, &kp, len * KEYPOINT_BYTES, true, |_| ())?;
            self.stats.write_passes += 1;
            out.extend(raw.chunks_exact(16).take(len as usize).map(|c| {
                let w =
                    |i: usize| u32::from_le_bytes(c[4 * i..4 * i + 4].try_into().expect("4 bytes"));
                Keypoint::ogm(w(0), w(1), w(2) as u8, w(3) as u8)
            }));
            start += len;
        }
        Ok(())
    }
}
