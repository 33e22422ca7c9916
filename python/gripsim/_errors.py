"""The exceptions of the gripsim package."""


class ScenarioError(ValueError):
    """A scenario that cannot be read: the file (with the ``--set`` that failed, if one did),
    the dotted key and the value at fault, and a hint when there is one.

    Attributes: ``file``, ``key``, ``value`` (empty strings when the error concerns the file
    as a whole), ``hint`` (``None`` or a sentence), ``message`` (what is wrong)."""

    def __init__(self, text, file="", key="", value="", hint=None, message=""):
        super().__init__(text)
        self.file = file
        self.key = key
        self.value = value
        self.hint = hint
        self.message = message or text


class RecordingError(ValueError):
    """A recording that cannot be read (missing, damaged, foreign, or of a kind not read
    here). Attributes: ``file`` (``None`` when the error concerns no one file), ``message``."""

    def __init__(self, text, file=None, message=""):
        super().__init__(text)
        self.file = file
        self.message = message or text
