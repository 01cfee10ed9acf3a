"""The one error of the design search's input (a bad variable, objective, constraint or
scenario option, with a message that names it and says what is allowed): every study's
:class:`studio.studies.api.StudyInputError`."""
from ..api import StudyInputError

__all__ = ["StudyInputError"]
