"""Batch processing of whole capture studies: one pipeline (label → calibrate → fill → solve → export) per
take, run as Dask tasks, each take's result a new review step of the session; resumable, with a report."""

from handmocap.core.batch.pipeline import Pipeline, load_pipeline, pipeline_from_dict, pipeline_toml, save_pipeline
from handmocap.core.batch.runner import BatchPlan, BatchProgress, open_study, plan_batch, run_batch
from handmocap.core.batch.task import process_take

__all__ = ["BatchPlan", "BatchProgress", "Pipeline", "load_pipeline", "open_study", "pipeline_from_dict",
           "pipeline_toml", "plan_batch", "process_take", "run_batch", "save_pipeline"]
