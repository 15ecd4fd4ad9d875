"""Recording a run to rerun: the observer (`recorder`), the live view beside the file (`live`), what
goes where in a recording and the viewer's blueprint (`layout`), and rerun and Arrow fed cheaply
(`arrow`)."""
