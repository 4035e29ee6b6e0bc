"""
The results table of a sweep: one row per run, a Parquet data set written as runs finish.

Layout of the output folder's table parts:

- ``table/part-*.parquet``: the data set (pyarrow, pandas, polars and DuckDB read the
  folder as one table); every part has the one schema :data:`SCHEMA`, whose fields carry
  their unit and meaning in their metadata (``unit``, ``description``);
- ``journal.jsonl``: each row as its run finishes, one JSON line, flushed at once: rows are
  kept even if the driver dies between two parts.  Opening the table moves the journal's
  rows into a part (those already in one are dropped: each run is in the table once).

A part is written to a hidden temporary file and renamed into place, so a reader never
sees half of one; readers skip names starting with ``.`` or ``_``.
"""

import json
import os
from pathlib import Path
import time
import uuid

import pyarrow as pa
import pyarrow.parquet as pq

__all__ = ['COLUMNS', 'ResultTable', 'SCHEMA', 'TABLE_FOLDER', 'JOURNAL', 'read_table',
           'finished_ids']

TABLE_FOLDER = 'table'
JOURNAL = 'journal.jsonl'
PART_ROWS = 10000
"""Rows per Parquet part (the last part of a session holds the rest)."""

_VECTOR = ('x', 'y', 'z')
_QUATERNION = ('x', 'y', 'z', 'w')
_F = pa.float64()
_S = pa.string()
_I = pa.int64()


def _vector(prefix, unit, description, axes=_VECTOR):
    return [(f'{prefix}_{axis}', _F, unit, f'{description} ({axis})') for axis in axes]


COLUMNS = [
    ('run_id', _S, '', 'content address: digest of the resolved scene, duration, substeps '
                       'and bag storage (rigid_body_sim/sweep/spec.py)'),
    ('status', _S, '', 'ok; diverged (the state turned non-finite: the final values are the '
                       'last finite state); invalid (the values make no valid scene)'),
    ('message', _S, '', 'why a run is not ok (empty when it is)'),
    ('scene', _S, '', "the scene's name"),
    ('integrator', _S, '', 'integrator name (rigid_body_sim.physics.INTEGRATORS)'),
    ('rate', _F, 'Hz', 'tick rate: one bag state per tick, dt = 1 / rate'),
    ('tolerance', _F, 'rad/s', 'error control, orientation error per simulated s; 0: off'),
    ('substeps', _I, '', 'integrator steps per tick (the least under error control)'),
    ('duration', _F, 's', 'simulated time asked for'),
    ('mass', _F, 'kg', 'body mass'),
    *[(f'inertia_{pair}', _F, 'kg m^2', f'inertia tensor about the COM, body frame ({pair})')
      for pair in ('xx', 'yy', 'zz', 'xy', 'xz', 'yz')],
    *_vector('initial_orientation', '', 'initial orientation, unit quaternion body to world',
             _QUATERNION),
    *_vector('initial_angular_velocity_body', 'rad/s', 'initial angular velocity, body frame'),
    *_vector('initial_position', 'm', 'initial COM position, world frame'),
    *_vector('initial_velocity', 'm/s', 'initial COM velocity, world frame'),
    ('imu_seed', _I, '', "seed of the IMU's noise (the bag's /imu)"),
    ('final_time', _F, 's', 'simulated time reached (below duration only if diverged)'),
    *_vector('final_orientation', '', 'final orientation, unit quaternion body to world',
             _QUATERNION),
    *_vector('final_angular_velocity_body', 'rad/s', 'final angular velocity, body frame'),
    *_vector('final_angular_momentum', 'kg m^2/s', 'final angular momentum about the COM, '
                                                   'world frame'),
    *_vector('final_position', 'm', 'final COM position, world frame'),
    *_vector('final_velocity', 'm/s', 'final COM velocity, world frame'),
    ('rotational_energy_drift', _F, '', '(T_rot(end) - T_rot(0)) / T_rot(0), T_rot = '
                                        'omega . L / 2'),
    ('angular_momentum_drift', _F, '', '(|L|(end) - |L|(0)) / |L|(0), L about the COM'),
    ('energy_drift', _F, '', '(E(end) - E(0)) / T(0): E kinetic plus potential energy, T(0) '
                             'the initial kinetic energy'),
    ('conserved', _S, '', 'what the physics of the scene conserves, comma-separated '
                          '(rotational_energy, angular_momentum, energy): the drift of these '
                          'is integration error, of the others physics'),
    ('orientation_error', _F, 'rad', "angle from the reference's final orientation (the "
                                     'exact torque-free flow); null where the scene has none'),
    ('position_error', _F, 'm', "distance from the reference's final COM position; null "
                                'where the scene has none'),
    ('steps', _I, '', 'integrator steps taken, error estimates included'),
    ('cpu_seconds', _F, 's', 'CPU time of the run on its worker: scene, simulation, bag, '
                             'reference'),
    ('cpu_per_simulated_second', _F, '', 'cpu_seconds / final_time'),
    ('wall_seconds', _F, 's', 'wall-clock time of the run on its worker'),
    ('host', _S, '', 'machine that ran it'),
    ('worker', _S, '', 'Dask worker address that ran it (empty: run in the driver)'),
    ('pid', _I, '', 'process that ran it'),
    ('bag', _S, '', 'its bag, relative to the output folder; null: no bag'),
    ('parameters', _S, '', "the spec's values for this run, JSON: key path -> value"),
    ('finished', pa.timestamp('ms', tz='UTC'), '', 'when the run finished'),
]
"""(name, Arrow type, unit, description) of every column, in order."""

SCHEMA = pa.schema([pa.field(name, kind, metadata={'unit': unit, 'description': description})
                    for name, kind, unit, description in COLUMNS])


def finished_ids(out):
    """Return the run ids in the table of output folder `out` (its parts and journal)."""
    ids = set()
    folder = Path(out) / TABLE_FOLDER
    if any(folder.glob('part-*.parquet')):
        ids.update(pq.read_table(folder, columns=['run_id']).column('run_id').to_pylist())
    ids.update(row['run_id'] for row in _journal_rows(Path(out) / JOURNAL))
    return ids


def read_table(out, columns=None):
    """Return the table of output folder `out` as a pyarrow Table (its parts)."""
    folder = Path(out) / TABLE_FOLDER
    if not any(folder.glob('part-*.parquet')):
        return SCHEMA.empty_table() if columns is None else SCHEMA.empty_table().select(columns)
    return pq.read_table(folder, columns=columns, schema=SCHEMA)


def _journal_rows(path):
    """Yield the complete rows of a journal (a last line cut by a kill is no row)."""
    try:
        with open(path, encoding='utf-8') as journal:
            for line in journal:
                if not line.endswith('\n'):
                    break
                try:
                    yield json.loads(line)
                except json.JSONDecodeError:
                    break
    except FileNotFoundError:
        return


class ResultTable:
    """
    The table of one output folder, open for adding rows (one writer at a time).

    :meth:`start` recovers a journal left by an earlier session and returns the ids in the
    table; :meth:`add` journals a row at once and writes a part every `part_rows` rows;
    :meth:`close` writes the rest.
    """

    def __init__(self, out, part_rows=PART_ROWS):
        """Work on output folder `out` (created if need be)."""
        self.out = Path(out)
        self.folder = self.out / TABLE_FOLDER
        self.part_rows = part_rows
        self.ids = set()
        self._rows = []
        self._journal = None
        self._parts = 0
        # Names of one session's parts: never those of another, even in the same second.
        self._session = uuid.uuid4().hex[:8]

    def start(self):
        """Recover the journal into a part; return the set of run ids in the table."""
        self.folder.mkdir(parents=True, exist_ok=True)
        for stale in self.folder.glob('.part-*'):
            stale.unlink()
        in_parts = set()
        if any(self.folder.glob('part-*.parquet')):
            in_parts = set(read_table(self.out, ['run_id']).column('run_id').to_pylist())
        recovered = {}
        for row in _journal_rows(self.out / JOURNAL):
            if row['run_id'] not in in_parts:
                recovered.setdefault(row['run_id'], row)
        self.ids = in_parts | set(recovered)
        if recovered:
            self._write_part(list(recovered.values()))
        self._journal = open(self.out / JOURNAL, 'w', encoding='utf-8')
        return set(self.ids)

    def add(self, row):
        """Add a finished run's row (a dict of the columns); a run already in is ignored."""
        if row['run_id'] in self.ids:
            return False
        self.ids.add(row['run_id'])
        self._journal.write(json.dumps(row, allow_nan=True) + '\n')
        self._journal.flush()
        self._rows.append(row)
        if len(self._rows) >= self.part_rows:
            self.flush()
        return True

    def flush(self):
        """Write the rows added since the last part as a part, then empty the journal."""
        if self._rows:
            self._write_part(self._rows)
            self._rows = []
        if self._journal is not None:
            self._journal.seek(0)
            self._journal.truncate()

    def close(self):
        """Write what is left and close the journal (removed: its rows are in parts)."""
        if self._journal is None:
            return
        self.flush()
        self._journal.close()
        self._journal = None
        (self.out / JOURNAL).unlink(missing_ok=True)

    def _write_part(self, rows):
        self._parts += 1
        name = (f'part-{time.strftime("%Y%m%dT%H%M%S")}-{self._session}-{self._parts:04d}'
                '.parquet')
        temporary = self.folder / ('.' + name)
        pq.write_table(pa.Table.from_pylist(rows, schema=SCHEMA), temporary)
        os.replace(temporary, self.folder / name)
