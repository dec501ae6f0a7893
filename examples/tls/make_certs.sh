#!/bin/sh
# Make a private CA (once) and one certificate signed by it, for Zenoh TLS.
#
#   examples/tls/make_certs.sh DIR NAME [ADDRESS ...]
#
# DIR/ca.pem and DIR/ca-key.pem are created when missing (keep ca-key.pem on
# the machine that signs, never copy it to the hosts); DIR/NAME.pem and
# DIR/NAME-key.pem are the certificate and key of one host, valid for the
# given IP addresses and DNS names (subjectAltName). Copy ca.pem, NAME.pem and
# NAME-key.pem to that host and point its deployment file at them.
set -eu
dir=$1; name=$2; shift 2
mkdir -p "$dir"
if [ ! -f "$dir/ca.pem" ]; then
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 30 -subj "/CN=cosim test CA" \
        -keyout "$dir/ca-key.pem" -out "$dir/ca.pem" 2>/dev/null
fi
san=""
for address in "$@" localhost 127.0.0.1; do
    case $address in
        *[!0-9.]*) entry="DNS:$address" ;;
        *) entry="IP:$address" ;;
    esac
    san="${san:+$san,}$entry"
done
openssl req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj "/CN=$name" \
    -keyout "$dir/$name-key.pem" -out "$dir/$name.csr" 2>/dev/null
printf 'subjectAltName=%s\nbasicConstraints=CA:FALSE\nkeyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth,clientAuth\n' "$san" > "$dir/$name.ext"
openssl x509 -req -in "$dir/$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca-key.pem" \
    -CAcreateserial -days 30 -extfile "$dir/$name.ext" -out "$dir/$name.pem" 2>/dev/null
rm -f "$dir/$name.csr" "$dir/$name.ext"
echo "$dir/$name.pem"
