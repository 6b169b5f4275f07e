"""The session folder: its manifest of subjects and takes, the edit journal, the snapshots, the take lock.

* :mod:`core.session.session` — :class:`Session` (a folder with a manifest) and :class:`OpenTake`;
* :mod:`core.session.journal` — the fsync'ed edit journal replayed on open;
* :mod:`core.session.storage` — snapshots of a review and the session's marker sets.

The review model itself (what an edit changes) is :mod:`core.review`.
"""

from handmocap.core.session.journal import Journal
from handmocap.core.session.session import TAKE_STATES, OpenTake, Session, SubjectEntry, TakeEntry

__all__ = ["TAKE_STATES", "Journal", "OpenTake", "Session", "SubjectEntry", "TakeEntry"]
