"""The payload range a controller holds (issue 38): the linearised sampled loop of each form with the
true plant carrying a payload the controller's model does not know (derive.dynamics.payload), its
largest stable payload mass (:mod:`.limits`), the sentences that state it (:mod:`.text`) and the
starter design that makes it cover the arm file's ``[payload]`` range (:mod:`.design`)."""
