"""The one error of the design search's input: a bad variable, objective, constraint or
scenario option, with a message that names it and says what is allowed."""


class StudyInputError(ValueError):
    """Bad input of ``study optimise`` (exit code 2); the message is the whole story."""
