"""The plan of a preset: every study's scenes and job batches, built once.

The Snakefile builds one :class:`Plan` when it is parsed; the rules take their jobs
(batch names, keys, runtimes), trace materials and report captions from it, so no scene is
built twice. Building the plan is also the configuration check: a bad value stops it with
the scene's one-line message, before anything runs.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import GranchainError
from .batches import Batch, batches, check_jobs, check_study
from .config import ConfigError, read_config, select_preset
from .studies import (ENGINE_ORDER, StudyScene, check_chain_scenes, preset_studies,
                      study_scenes, vibrometer_scenes, vibrometer_settings)


@dataclass(frozen=True, eq=False)
class Plan:
    """A preset (``name``, validated ``preset`` mapping) with the study scenes and job
    batches of every study (``studies``: the chapter's and the field's the preset has), in
    table order; ``vibrometer``: the scenes of the optional vibrometer study (empty
    without it; one job, :mod:`.vibrometer`); ``chains``: lammps_check's field chains,
    which only the engine comparison runs (:func:`.studies.check_chain_scenes`)."""
    name: str
    preset: dict
    scenes: dict[str, list[StudyScene]]
    batches: dict[str, list[Batch]]
    vibrometer: tuple[StudyScene, ...] = ()
    chains: tuple[StudyScene, ...] = ()

    @property
    def studies(self) -> list[str]:
        """The preset's ensemble studies, in order (each has a table)."""
        return list(self.scenes)

    @classmethod
    def build(cls, config: dict) -> Plan:
        """The plan of the preset ``config['preset']`` of a validated configuration."""
        name, preset = select_preset(config)
        scenes, jobs = {}, {}
        for study in preset_studies(preset):
            try:
                scenes[study] = study_scenes(preset, study)
                check_study(preset, name, study, scenes[study])
                jobs[study] = batches(preset, study, scenes=scenes[study])
                check_jobs(preset, name, study, jobs[study], scenes[study])
            except ConfigError as exc:
                raise ConfigError(str(exc).replace("at 'studies.", f"at 'presets.{name}.studies.",
                                                   1)) from None
        try:
            vib = tuple(vibrometer_scenes(preset))
            for ss in vib:
                vibrometer_settings(preset, ss)         # every instrument setting is valid
            chains = tuple(check_chain_scenes(preset))
        except ConfigError as exc:
            raise ConfigError(str(exc).replace("at 'studies.", f"at 'presets.{name}.studies.",
                                               1)) from None
        return cls(name, preset, scenes, jobs, vib, chains)

    def batch(self, study: str, name: str) -> Batch:
        """The batch called ``name`` (e.g. reference_000) of a study."""
        for b in self.batches[study]:
            if b.name == name:
                return b
        raise GranchainError(f"study '{study}' has no batch '{name}' in preset '{self.name}'")

    def materials(self, study: str) -> list[str]:
        """The material of each scene of a study, in table order."""
        return [ss.material for ss in self.scenes[study]]

    def engines(self, study: str) -> list[str]:
        """The engines a study runs, in table order."""
        return [e for e in ENGINE_ORDER if any(e in ss.engines for ss in self.scenes[study])]

    def scene_hashes(self, study: str) -> list[str]:
        return [ss.scene.hash for ss in self.scenes[study]]


def load_config(path, preset: str | None = None, engine: str | None = None
                ) -> tuple[str, dict]:
    """(name, validated preset) of a workflow configuration file, e.g. config/config.yaml,
    with its ensemble studies on ``engine`` if given (as ``--config engine=...``); every
    study scene and batch of the preset is built, so a bad value fails here."""
    plan = Plan.build(read_config(path, preset, engine))
    return plan.name, plan.preset
