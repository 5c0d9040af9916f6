"""A tiny label format for the registry test: the whole of it is this class (a real format
module adds ``FORMAT = CountFormat()`` and one line in ``formats.registry.BUILTIN``)."""

from aerial_synth.formats.registry import LabelFormat


class CountFormat(LabelFormat):
    """count/pictures/<name>.png, count/<split>/<name>.count (number of kept vehicles),
    count/total.txt."""

    name = "count"
    description = "number of labelled vehicles per image (registry test)"

    def image_path(self, split, file_name):
        return f"{self.folder}/pictures/{file_name}"

    def label_path(self, split, name):
        return f"{self.folder}/{split}/{name}.count"

    def label_text(self, record):
        return f"{sum(1 for a in record.annotations if a.kept)}\n"

    def aggregate_files(self, records, info):
        n = sum(1 for r in records for a in r.annotations if a.kept)
        return {f"{self.folder}/total.txt": f"images {len(records)} vehicles {n}\n"}


FORMAT = CountFormat()
