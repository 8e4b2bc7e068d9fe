"""The one error type for bad user input (case files, meshes, geometry files).

The CLI prints it as a single line and exits non-zero, without a traceback.
"""


class InputError(Exception):
    """Bad user input: names the file, the key and the offending value."""

    def __init__(self, file, key, value, message):
        self.file, self.key, self.value, self.message = str(file), key, value, message
        where = self.file if key is None else f"{self.file}: {key} = {value!r}"
        super().__init__(f"{where}: {message}")
