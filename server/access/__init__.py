"""Who may do what: users, roles and tokens (``accounts``), the token checks of a request
(``auth``) and the audit log of every mutating request (``audit``)."""
