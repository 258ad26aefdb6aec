"""`vtrack setup`: a page on 127.0.0.1 where count lines, gates, zones, the region of
interest and calibration points are drawn on a video's first frame and saved to the config
(`config_io`), served by `server`, drawn by `page`."""
