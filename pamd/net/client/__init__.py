"""The client library's Zenoh end (`client.Client`): `pamd status`, `pamd cmd`,
`pamd watch` and `pamd.connect` (`pamd.view.client`) use it; it knows the key space
and the verbs' specs, nothing of the daemon."""
