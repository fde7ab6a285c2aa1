"""The dense track's columns: its summary's (``summary.summarize_dense`` fills them) and the
per-frame ones its leaderboard keeps."""

DENSE_COLUMNS = ("frames", "status", "failures", "precision", "recall", "precision_start", "recall_start",
                 "icp_failures", "wrong_steps", "ate_mm", "ate_deg", "final_drift_mm", "step_error_mm",
                 "step_error_deg", "map_points", "compression_pct", "map_median_mm", "map_p95_mm", "icp_ms",
                 "fusion_ms", "fps")
# the per-frame columns its leaderboard keeps (the map picture's): poses, timings, ICP's outcome
FRAME_COLUMNS = ("est_x", "est_y", "est_z", "true_x", "true_y", "true_z", "final_map", "icp_s", "fusion_s", "icp_failed",
                 "icp_reason", "step_error_mm", "map_points")
