#!/usr/bin/env bash
# Makes a TEST public-key infrastructure for torqued's opt-in DDS Security (docs/security.md), offline, with
# openssl only: an identity CA, a permissions CA, an identity (EC prime256v1 key + certificate) per participant
# role (daemon, subscriber), and governance and permissions documents signed (S/MIME) by the permissions CA.
# Usage: tools/scripts/make-test-pki.sh OUT_DIR [TOPIC_PREFIX (default torque)] [DAYS (default 30)]
# Writes into OUT_DIR: identity_ca.pem, permissions_ca.pem, {daemon,subscriber}_{cert,key}.pem,
# governance.p7s, permissions.p7s (and the unsigned XML beside them). The CA keys stay in OUT_DIR/private.
# Test keys: unencrypted, short-lived; a real deployment keeps the CA keys off the vehicle (see the doc).
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:?usage: make-test-pki.sh OUT_DIR [TOPIC_PREFIX] [DAYS]}
prefix=${2:-torque}
days=${3:-30}
mkdir -p "$out/private"
chmod 700 "$out/private"
cd "$out"
ec_key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:prime256v1 -out "$1" 2>/dev/null; }
ca() {  # name, subject
  ec_key "private/$1_ca_key.pem"
  openssl req -x509 -new -key "private/$1_ca_key.pem" -out "$1_ca.pem" -days "$days" -subj "$2" \
    -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign,digitalSignature
}
ca identity "/O=torqued test PKI/CN=torqued identity CA"
ca permissions "/O=torqued test PKI/CN=torqued permissions CA"
subject() { openssl x509 -noout -subject -nameopt RFC2253 -in "$1" | sed 's/^subject=//'; }
for role in daemon subscriber; do
  ec_key "${role}_key.pem"
  openssl req -new -key "${role}_key.pem" -subj "/O=torqued test PKI/CN=torqued ${role}" -out "private/${role}.csr"
  openssl x509 -req -in "private/${role}.csr" -CA identity_ca.pem -CAkey private/identity_ca_key.pem \
    -CAcreateserial -CAserial private/identity_ca.srl -days "$days" -out "${role}_cert.pem" 2>/dev/null
  openssl verify -CAfile identity_ca.pem "${role}_cert.pem" >/dev/null
done
not_before=$(date -u -d '-1 hour' +%Y-%m-%dT%H:%M:%S)
not_after=$(date -u -d "+${days} days" +%Y-%m-%dT%H:%M:%S)
cp "$here/config/security/governance.xml" governance.xml
sed -e "s|@DAEMON_SUBJECT@|$(subject daemon_cert.pem)|" -e "s|@SUBSCRIBER_SUBJECT@|$(subject subscriber_cert.pem)|" \
  -e "s|@NOT_BEFORE@|$not_before|g" -e "s|@NOT_AFTER@|$not_after|g" -e "s|@TOPIC_PREFIX@|$prefix|g" \
  "$here/config/security/permissions.xml.in" > permissions.xml
! grep -q "@[A-Z_]*@" permissions.xml || { echo "make-test-pki.sh: unfilled field in permissions.xml" >&2; exit 1; }
for doc in governance permissions; do
  openssl smime -sign -in "$doc.xml" -text -out "$doc.p7s" -signer permissions_ca.pem \
    -inkey private/permissions_ca_key.pem
  openssl smime -verify -in "$doc.p7s" -CAfile permissions_ca.pem -out /dev/null 2>/dev/null \
    || { echo "make-test-pki.sh: $doc.p7s does not verify" >&2; exit 1; }
done
echo "make-test-pki.sh: test PKI in $out (roles daemon, subscriber; topics $prefix/*; valid $days days)"
