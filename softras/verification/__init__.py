"""Checking pictures: softras's against GL's, and any renderer's against GL's.

- `metrics`: differences, SSIM, FLIP and the comparison report;
- `ambiguity`, `verifier`: what the GL specification leaves open, and the
  verdicts (strict and spec profiles);
- `conformance`, `runner`, `report`: the conformance run over scene files in
  supervised workers, and its HTML / JSON / JUnit reports;
- `golden`: golden images with provenance;
- `explain`: one pixel's history through every stage;
- `ground_truth`: the supersampled reference for softras-only filters.
"""
