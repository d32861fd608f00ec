"""What each stage read, kept and dropped: one typed record for the result's ``samples`` block."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

__all__ = ["SampleCounts"]


@dataclass(frozen=True)
class SampleCounts:
    """Sample counts of one calibration, stage by stage (read → sync → gates → pairs).

    read_a, read_b: samples read per stream; duplicates_dropped_a/_b: exact duplicate stamps the
    reader removed; recovered_truncated_a/_b: messages salvaged from a log cut short by a crash;
    synced: samples associated in time; dropped_outside_span: samples of the
    reference stream outside the other's time span; dropped_timestamp_gate: samples whose
    neighbours were farther than ``max_dt``; dropped_pose_jump: samples the pose-jump gate removed
    (jumps_a/_b per stream, accepted_jumps: jumps that persisted and were accepted as the new
    pose); synced_kept: samples left; keyframes: samples the pair strategy drew from;
    candidate_pairs: pairs it could form; pairs: pairs solved.
    """

    read_a: int = 0
    read_b: int = 0
    duplicates_dropped_a: int = 0
    duplicates_dropped_b: int = 0
    recovered_truncated_a: int = 0
    recovered_truncated_b: int = 0
    synced: int = 0
    dropped_outside_span: int = 0
    dropped_timestamp_gate: int = 0
    dropped_pose_jump: int = 0
    jumps_a: int = 0
    jumps_b: int = 0
    accepted_jumps: int = 0
    synced_kept: int = 0
    keyframes: int = 0
    candidate_pairs: int = 0
    pairs: int = 0

    @classmethod
    def of(cls, *stage_counts: dict[str, Any], **more: int) -> SampleCounts:
        """Merge the count dicts the stages return (unknown keys are a programming error)."""
        merged: dict[str, Any] = {}
        for d in (*stage_counts, more):
            merged.update(d)
        return cls(**{k: int(v) for k, v in merged.items()})

    def as_dict(self) -> dict[str, int]:
        return asdict(self)

    def losses(self) -> dict[str, int]:
        """The counts of samples some stage removed, by stage (the report's "what each gate dropped" panel)."""
        names = ("duplicates_dropped_a", "duplicates_dropped_b", "dropped_outside_span", "dropped_timestamp_gate",
                 "dropped_pose_jump", "jumps_a", "jumps_b")
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name in names}
