"""The grasp dataset kept in git: validated tabletop grasps added batch by batch (layout: ``dataset.layout``).

``add_batch`` appends a finished batch, ``load_dataset`` reads grasps back, ``write_card`` regenerates CARD.md.
"""

from dexlite_pipeline.dataset.card import write_card
from dexlite_pipeline.dataset.layout import BatchRecord, code_version, config_digest, default_rebuild, machine_description, utc_timestamp
from dexlite_pipeline.dataset.store import add_batch, export_dexgraspnet, load_dataset, merge_datasets, present_objects
from dexlite_pipeline.dataset.summary import dataset_summary
from dexlite_pipeline.dataset.validation import DatasetError

__all__ = [
    "BatchRecord",
    "DatasetError",
    "add_batch",
    "code_version",
    "config_digest",
    "dataset_summary",
    "default_rebuild",
    "export_dexgraspnet",
    "load_dataset",
    "machine_description",
    "merge_datasets",
    "present_objects",
    "utc_timestamp",
    "write_card",
]
