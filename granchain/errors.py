"""User-facing errors: one line, naming the field and the fix.

Every error a user can cause by bad input is a :class:`GranchainError`. The CLI
prints ``str(err)`` on one line and exits with status 2; it never shows a traceback
for these.
"""


class GranchainError(Exception):
    """An error caused by user input or the environment, with a one-line message."""


class SceneError(GranchainError):
    """A scene file (or an override) is invalid.

    ``field`` is the dotted path of the offending key, ``fix`` says what to do.
    """

    def __init__(self, field: str, problem: str, fix: str):
        self.field, self.problem, self.fix = field, problem, fix
        # a key the user wrote may hold a quote: shown escaped, so the field's quotes
        # still delimit it
        name = _cut(field, MAX_FIELD).replace("\\", "\\\\").replace("'", "\\'")
        super().__init__(f"scene field '{name}': {_cut(problem, MAX_PART)}; "
                         f"{_cut(fix, MAX_PART)}")


# A message stays short whatever the scene holds: a key's path (which may hold a key the
# user wrote, of any length) and each part are cut to these many characters.
MAX_FIELD = 100
MAX_PART = 500


def _cut(text: str, limit: int) -> str:
    text = str(text)
    return text if len(text) <= limit else text[:limit - 3] + "..."
