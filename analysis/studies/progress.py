"""Progress shown while long work runs: a rich display of tasks (points done, cache hits, time left).

:class:`Display` is what a scene run shows; :class:`Reporter` turns the
``progress(stage, done, total)`` callbacks of an analysis (a limit-cycle
search, a continuation, a map) into its tasks.
"""


class Display:
    """A rich progress display: points done, cache hits, time left (silent when off).

    It starts with the first task that has work left, showing the tasks complete before it: a run that
    finds everything done (in the cache) has nothing to wait for, and neither shows nor loads a display."""

    def __init__(self, enabled, title):
        self.enabled, self.title = enabled, title
        self.progress = None
        self._complete = []  # tasks complete when added, before the display started

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.stop()

    def _start(self):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
        from rich.table import Column

        label = Column(max_width=32, no_wrap=True, overflow="ellipsis")
        self.progress = Progress(TextColumn("{task.description}", table_column=label), BarColumn(bar_width=20),
                                 MofNCompleteColumn(), TextColumn("[cyan]{task.fields[hits]} cached"),
                                 TextColumn("time left"),
                                 TimeRemainingColumn(compact=True))
        self.progress.console.print(f"[bold]{self.title}")
        self.progress.start()
        for label, total, done, hits in self._complete:
            self.progress.add_task(label, total=total, completed=done, hits=hits)

    def add(self, label, total, done, hits):
        if not self.enabled or total == 0:
            return None
        if self.progress is None:
            if done >= total:  # nothing to wait for (never advanced): shown if the display starts later
                self._complete.append((label, total, done, hits))
                return None
            self._start()
        return self.progress.add_task(label, total=total, completed=done, hits=hits)

    def advance(self, task, n):
        if task is not None:
            self.progress.advance(task, n)


class Reporter:
    """``progress(stage, done, total)``: one task of a :class:`Display` per stage (done None: a step of unknown
    count). Use it as a context manager, or it closes itself when a stage completes its last step."""

    def __init__(self, title, enabled=True):
        self.display = Display(enabled, title)
        self.tasks = {}

    def __call__(self, stage, done, total):
        if done is None or total is None:
            return
        task = self.tasks.get(stage)
        if stage not in self.tasks:
            task = self.tasks[stage] = self.display.add(stage, total, 0, 0)
        if task is not None:
            self.display.progress.update(task, completed=done, total=total)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.display.__exit__(*exc)
