"""Config sections every stage shares: sharding, runtime, output location."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

#: Config keys that do not change what a stage writes; left out of the config hash.
NON_OUTPUT_KEYS = ("out", "shard", "runtime", "artifacts_root")


class Strict(BaseModel):
    """Base for config schemas: immutable, unknown keys are errors."""

    model_config = ConfigDict(frozen=True, extra="forbid")


class ShardConfig(Strict):
    """Which deterministic slice of the work this process does (one job per shard)."""

    index: int = Field(0, ge=0, description="this shard's index, 0-based")
    count: int = Field(1, ge=1, description="number of shards the work is split into")

    @model_validator(mode="after")
    def _index_in_range(self) -> ShardConfig:
        if self.index >= self.count:
            raise ValueError(f"shard.index {self.index} must be < shard.count {self.count}")
        return self


class RuntimeConfig(Strict):
    """How to run, not what to compute: never changes the output bytes."""

    workers: int = Field(0, ge=0, description="worker processes; 0 = the CPUs this process may use")
    threads: int = Field(
        0, ge=0, description="torch threads of inference; 0 = the CPUs this process may use"
    )


class StageConfig(Strict):
    """Fields every stage config has."""

    out: str = Field(description="output folder")
    artifacts_root: str = Field("artifacts", description="default root of output folders")
    seed: int = Field(0, ge=0, description="base seed; sample i is seeded from (seed, i)")
    shard: ShardConfig = Field(default_factory=ShardConfig)
    runtime: RuntimeConfig = Field(default_factory=RuntimeConfig)


class TrainingStageConfig(StageConfig):
    """A stage that trains a network. A backward pass sums its gradients in an order that
    depends on the number of threads (oneDNN's convolutions, scatter sums), so the thread
    count is part of what the stage computes: `train.threads`, in the config hash, not
    `runtime.threads`, which must stay 0 here."""

    @field_validator("runtime")
    @classmethod
    def _threads_are_numerics(cls, runtime: RuntimeConfig) -> RuntimeConfig:
        if runtime.threads:
            raise ValueError(
                "a training stage computes with train.threads (the thread count changes "
                "the trained weights, so it is part of the config)"
            )
        return runtime
