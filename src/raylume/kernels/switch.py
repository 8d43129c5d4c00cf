"""A dispatch over kind modules (the materials' and the lights' registries): for one question, one
kernel function with a branch per kind, written out as source from the registry's list of
modules, as one written by hand would be:

    def question(params):
        kind = <kind expression>
        if kind == first.KIND:
            return first.question(params)
        ...                                  (one branch per module)
        return unknown

`unknown` answers a kind that no module of the list defines: never another kind's answer."""


def kind_switch(question: str, params: str, kind: str, modules, unknown, decorator, attribute: str | None = None):
    """The dispatch of `question` (each module's function of that name, or of `attribute`)
    over `modules`; `kind` is the expression of the params that gives the row's kind."""
    attribute = attribute or question
    namespace = {"unknown": unknown}
    lines = [f"def {question}({params}):", f"    kind = {kind}"]
    for i, module in enumerate(modules):
        namespace[f"kind_{i}"] = getattr(module, attribute)
        lines += [f"    if kind == {module.KIND}:", f"        return kind_{i}({params})"]
    lines.append("    return unknown")
    exec(compile("\n".join(lines), f"<raylume kind switch: {question}>", "exec"), namespace)
    function = namespace[question]
    function.__doc__ = f"{question} of the row's kind: {', '.join(m.__name__.rsplit('.', 1)[-1] for m in modules)}."
    return decorator(function)
