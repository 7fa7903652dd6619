"""The run folder's format, written and read: ``run.json`` (:mod:`.folder`, which also guards
the folder with its lock), ``timeseries.csv`` and ``state.h5`` (:mod:`.series_files`, read back by
:mod:`.reader`), ``solution.xdmf`` (:mod:`.xdmf_writer`, :mod:`.xdmf_nodes`; read back by
:mod:`.xdmf_reader`), the crash-safe HDF5 journal (:mod:`.journal`), checkpoints
(:mod:`.checkpoint`) and the set of files of one run (:mod:`.run_files`).

Nothing here knows the method: the time loop (:mod:`sdm_dolfinx.run`) hands these writers
arrays and Functions, and the post-processing reads them back.
"""
from sdm_dolfinx.io.checkpoint import CheckpointError
from sdm_dolfinx.io.folder import FolderInUseError, RunFolderError, check_out, read_info
from sdm_dolfinx.io.reader import PostprocessError, StateReader, read_timeseries
from sdm_dolfinx.io.run_files import RunFileError

__all__ = ["CheckpointError", "FolderInUseError", "RunFolderError", "check_out", "read_info", "PostprocessError",
           "StateReader", "read_timeseries", "RunFileError"]
